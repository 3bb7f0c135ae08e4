#!/usr/bin/env bash
# The guide's example method reaches every front with no front edited.
#   test_gain_fronts.sh GAIN_LIB_DIR EDGEWISE_BIN MAKE_FIXTURES OFX_DESCRIBE_TEST PYTHON_DIR PYTHON3 GAIN_SRC_DIR GUIDE
# GAIN_LIB_DIR holds a libedgewise with the "gain" filter (tests/gain). The
# CLI, the node library, the Python package and the OFX bundle are the
# ordinary builds; LD_LIBRARY_PATH / EDGEWISE_LIB make them load that
# library instead of build/lib's. Each check first proves the swap worked
# (the front shows gain), then that it works (runs it, shows its enum names).
set -u
LIB="$1"; EW="$2"; FIX="$3"; OFX="$4"; PY="$5"; PY3="${6:-}"; SRC="$7"; GUIDE="$8"
. "$(dirname "$0")/../lib/harness.sh"

# ---- the example is the files the guide counts: kernel, op file, test (the
# rest of tests/gain is this harness: its CMakeLists.txt and this script)
ls "$SRC" | grep -vx -e CMakeLists.txt -e test_gain_fronts.sh | sort >"$T/files"
printf '%s\n' filter_gain.c gain_px.h test_gain.c >"$T/want"
n=$(wc -l <"$T/files")
if diff "$T/want" "$T/files" >"$T/err" && grep -q "That is \*\*$n files\*\* for a method that runs on the CPU" "$GUIDE"; then
  ok example_is_the_guides_files
else
  echo "the guide ($GUIDE) should count these $n files" >>"$T/err"; bad example_is_the_guides_files
fi
rm -f "$T/err"
export LD_LIBRARY_PATH="$LIB${LD_LIBRARY_PATH:+:$LD_LIBRARY_PATH}"

# the ordinary CLI without the swap does not know gain: the test can fail
if LD_LIBRARY_PATH= "$EW" filter --help 2>/dev/null | grep -q -- "--method gain:"; then
  bad "the ordinary library already has gain (the test would prove nothing)"
fi

# ---- CLI: listed, its parameters generated, runs
"$EW" filter --help >"$T/help" 2>"$T/err"
grep -q -- "--method gain: multiplies the colour" "$T/help" && ok cli_lists_gain || bad cli_lists_gain
grep -q -- "--gain F .*0\.\.100 (default 1)" "$T/help" && ok cli_gain_param || bad cli_gain_param
grep -q -- "--alpha NAME .*scale, keep (default scale)" "$T/help" && ok cli_gain_enum_names || bad cli_gain_enum_names
"$FIX" "$T" >/dev/null || { echo "0 passed, 1 failed"; exit 1; }
IN="$T/two_layers.exr"
"$EW" filter "$IN" -o "$T/g1.exr" --method gain --gain 1 2>"$T/err" && \
  "$EW" compare "$T/g1.exr" "$IN" | grep -q "PSNR inf" && ok cli_gain_1_is_identity || bad cli_gain_1_is_identity
"$EW" filter "$IN" -o "$T/g2.exr" --method gain --gain 2 --alpha keep 2>"$T/err" && \
  grep -q "gain 2, alpha keep" "$T/err" && ok cli_runs_gain || bad cli_runs_gain
"$EW" compare "$T/g2.exr" "$IN" | grep -Eq "PSNR [0-9.]+ dB" && ok cli_gain_2_changes || bad cli_gain_2_changes
"$EW" filter "$IN" -o "$T/g3.exr" --method gain --alpha half >"$T/out" 2>"$T/err"
[ $? -eq 2 ] && grep -q "unknown --alpha 'half' (scale, keep)" "$T/err" && ok cli_gain_bad_choice || bad cli_gain_bad_choice

# ---- nodes: the filter node's choices and the method's parameters
"$EW" nodes filter >"$T/nodes" 2>"$T/err"
grep -q "gain" "$T/nodes" && ok nodes_list_gain || bad nodes_list_gain
cat >"$T/g.json" <<JSON
{"edgewise_graph": 1, "nodes": {"in": {"type": "read", "params": {"path": "$IN", "layer": "ViewLayer"}},
           "g": {"type": "filter", "params": {"filter": "gain", "gain": 2, "alpha": "keep"}, "inputs": {"color": "in.color"}},
           "out": {"type": "write", "params": {"path": "$T/n.exr"}, "inputs": {"image": "g"}}}}
JSON
"$EW" graph run "$T/g.json" >"$T/out" 2>"$T/err" && [ -s "$T/n.exr" ] && ok graph_runs_gain || bad graph_runs_gain

# ---- Python (and so Blender's add-on, which reads the same node types)
# An interpreter cannot load a sanitizer-built library without preloading
# its runtime (the sanitizer stage of CI leaves Python out likewise).
if [ -n "$PY3" ] && ldd "$LIB/libedgewise.so" 2>/dev/null | grep -q 'lib[at]san'; then
  echo "skip python (the library is built with a sanitizer)"
elif [ -n "$PY3" ]; then
  EDGEWISE_LIB="$LIB" PYTHONPATH="$PY" "$PY3" - >"$T/out" 2>"$T/err" <<'PYEOF'
import edgewise
f = edgewise.node_type("filter")
choices = [p for p in f["params"] if p["name"] == "filter"][0]["choices"]
assert "gain" in choices, choices
g = edgewise.node_type("filter", "gain")
ps = {p["name"]: p for p in g["params"]}
assert ps["gain"]["type"] == "float" and ps["gain"]["max"] == 100.0, ps["gain"]
assert ps["alpha"]["type"] == "enum" and ps["alpha"]["choices"] == ["scale", "keep"], ps["alpha"]
print("python ok")
PYEOF
  grep -q "python ok" "$T/out" && ok python_sees_gain || bad python_sees_gain
else
  echo "skip python (no python3)"
fi

# ---- OFX: the describe tests, on the plugin's sources linked with this
# registry (the bundle carries its library), expect a gain plugin
if [ -x "$OFX" ]; then
  EW_EXPECT_PLUGIN=org.edgewise.filter.gain "$OFX" >"$T/err" 2>&1 && ok ofx_describe_with_gain || bad ofx_describe_with_gain
fi

finish
