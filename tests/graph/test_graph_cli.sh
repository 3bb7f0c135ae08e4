#!/usr/bin/env bash
# `edgewise graph` and `edgewise nodes` on good and bad input. Usage:
#   test_graph_cli.sh EDGEWISE_BIN SAMPLE_DIR EXAMPLES_DIR
# Prints "N passed, N failed" and exits non-zero on any failure.
set -u
EW="$1"; SAMPLE=$(cd "$2" && pwd); EXAMPLES=$(cd "$3" && pwd)
. "$(dirname "$0")/../lib/harness.sh"

graph() { printf '%s' "$2" >"$T/$1"; }

IN="$SAMPLE/cornell/f0001_spp0004.exr"
mkdir -p "$T/seq"
for f in 1 2 3; do cp "$IN" "$T/seq/render_000$f.exr"; done

# ---- help and listing, generated from the descriptors
"$EW" --help | grep -q "graph run FILE" && ok main_help_lists_graph || bad main_help_lists_graph
"$EW" graph --help | grep -q -- "--set NODE.PARAM=VALUE" && ok graph_help || bad graph_help
"$EW" nodes >"$T/nodes" 2>&1 && ok nodes_runs || bad nodes_runs
missing=""
for t in read write input output denoise filter pyramid bilateral atrous dof outlier demodulate remodulate \
         temporal colorspace display metrics add multiply mix shuffle; do
  grep -q "^$t (v" "$T/nodes" || missing="$missing $t"
done
[ -z "$missing" ] && ok nodes_lists_every_type || bad "nodes_lists_every_type (missing:$missing)"
grep -q "spatial_rate.*float = 8 \[1, 256\]" "$T/nodes" && ok nodes_lists_library_params || bad nodes_lists_library_params
"$EW" nodes --json >"$T/nodes.json" && python3 -c "import json,sys; d=json.load(open(sys.argv[1])); assert 'methods' in d['denoise'] and d['bilateral']['params']" "$T/nodes.json" \
  && ok nodes_json || bad nodes_json
"$EW" nodes bilateral | grep -q "sigma_range" && ok nodes_one_type || bad nodes_one_type
expect nodes_unknown_type 2 "unknown node type 'blur'" -- "$EW" nodes blur

# ---- usage errors (exit 2)
expect usage_no_subcommand 2 "needs a subcommand" -- "$EW" graph
expect usage_no_file 2 "needs a graph file" -- "$EW" graph run
expect usage_bad_frames 2 "--frames expects" -- "$EW" graph run x.json --frames 3-1
expect usage_bad_set 2 "--set expects NODE.PARAM=VALUE" -- "$EW" graph run x.json --set radius=3

# ---- a good graph: the example, outputs redirected
expect example_runs 0 "" -- "$EW" graph run "$EXAMPLES/denoise_dof_display.json" \
  --set preview.path="$T/p.png" --set pixels.path="$T/p.exr" --report "$T/report.json"
[ -s "$T/p.png" ] && [ -s "$T/p.exr" ] && ok example_outputs_written || bad example_outputs_written
grep -q "PSNR" "$T/out" && ok summary_has_metrics || bad summary_has_metrics
python3 -c "import json,sys; r=json.load(open(sys.argv[1])); assert r['ok'] and r['frames'][0]['metrics']['quality']['psnr'] > 20" "$T/report.json" \
  && ok report_json || bad report_json
expect check_only 0 "" -- "$EW" graph check "$EXAMPLES/denoise_dof_display.json" --set preview.path="$T/c.png" --set pixels.path="$T/c.exr"
grep -q "valid" "$T/out" && [ ! -e "$T/c.png" ] && ok check_writes_nothing || bad check_writes_nothing
expect set_bad_value 1 "node 'denoised' parameter 'spatial_rate' = 0 is outside [1, 256]" -- "$EW" graph run "$EXAMPLES/denoise_dof_display.json" --set denoised.spatial_rate=0
expect set_unknown_param 1 "node 'lens': unknown parameter 'blades'" -- "$EW" graph run "$EXAMPLES/denoise_dof_display.json" --set lens.blades=6
expect set_unknown_node 2 "no node 'nope'" -- "$EW" graph run "$EXAMPLES/denoise_dof_display.json" --set nope.x=1
# enum parameters by name, as the CLI takes them (the example gives "weights": "analytic")
grep -q '"weights": "analytic"' "$EXAMPLES/denoise_dof_display.json" && ok example_enum_by_name || bad example_enum_by_name
expect enum_by_name 0 "" -- "$EW" graph check "$EXAMPLES/denoise_dof_display.json" --set lens.method=separable --set lens.weights=trained --set preview.path="$T/c.png" --set pixels.path="$T/c.exr"
expect enum_unknown_name 1 "unknown value 'exact-ish' (one of: pyramid, bilateral, separable)" -- "$EW" graph check "$EXAMPLES/denoise_dof_display.json" --set lens.method=exact-ish
# outputs are checked before any work: an unwritable write path fails the check
expect check_unwritable_output 1 "directory '$T/none' does not exist" -- "$EW" graph run "$EXAMPLES/denoise_dof_display.json" --set preview.path="$T/none/p.png" --set pixels.path="$T/p2.exr"
[ ! -e "$T/p2.exr" ] && ok unwritable_output_writes_nothing || bad unwritable_output_writes_nothing

# ---- sequences
graph seq.json '{"edgewise_graph": 1, "nodes": {
  "r": {"type": "read", "params": {"path": "seq/render_####.exr"}},
  "f": {"type": "outlier", "params": {"k": 2}, "inputs": {"color": "r.color"}},
  "w": {"type": "write", "params": {"path": "seqout/out_####.png"}, "inputs": {"image": "f"}}}}'
mkdir -p "$T/seqout"
expect sequence_all_frames 0 "" -- "$EW" graph run "$T/seq.json"
[ -s "$T/seqout/out_0001.png" ] && [ -s "$T/seqout/out_0003.png" ] && ok sequence_outputs || bad sequence_outputs
rm -f "$T"/seqout/*
expect sequence_frames_option 0 "" -- "$EW" graph run "$T/seq.json" --frames 2-3
[ ! -e "$T/seqout/out_0001.png" ] && [ -s "$T/seqout/out_0002.png" ] && [ -s "$T/seqout/out_0003.png" ] \
  && ok frames_option_limits || bad frames_option_limits
expect frame_missing 1 "frame 4 of" -- "$EW" graph run "$T/seq.json" --frames 3-4
graph nomatch.json '{"edgewise_graph": 1, "nodes": {
  "r": {"type": "read", "params": {"path": "seq/shot_####.exr"}},
  "w": {"type": "write", "params": {"path": "x_####.png"}, "inputs": {"image": "r.color"}}}}'
expect pattern_matches_nothing 1 "the frame pattern" -- "$EW" graph run "$T/nomatch.json"
grep -q "matches no file" "$T/err" && ok pattern_message || bad pattern_message

# ---- bad graph files
graph syntax.json '{"edgewise_graph": 1,
  "nodes": {"a": {"type": "add" "inputs": {}}}}'
expect malformed_json 1 "syntax.json:2:" -- "$EW" graph run "$T/syntax.json"
expect missing_graph 1 "cannot read graph" -- "$EW" graph run "$T/nope.json"
graph typeerr.json "{\"edgewise_graph\": 1, \"nodes\": {
  \"r\": {\"type\": \"read\", \"params\": {\"path\": \"$IN\"}},
  \"d\": {\"type\": \"denoise\", \"inputs\": {\"color\": \"r.color\", \"albedo\": \"r.normal\"}},
  \"w\": {\"type\": \"write\", \"params\": {\"path\": \"t.exr\"}, \"inputs\": {\"image\": \"d\"}}}}"
expect type_error 1 "node 'd' input 'albedo': type error" -- "$EW" graph run "$T/typeerr.json"
graph unknownpass.json "{\"edgewise_graph\": 1, \"nodes\": {
  \"r\": {\"type\": \"read\", \"params\": {\"path\": \"$IN\", \"pass\": \"Emit\"}},
  \"w\": {\"type\": \"write\", \"params\": {\"path\": \"t.exr\"}, \"inputs\": {\"image\": \"r.image\"}}}}"
expect unknown_pass 1 "no pass 'Emit' in layer 'ViewLayer'" -- "$EW" graph run "$T/unknownpass.json"
graph novector.json "{\"edgewise_graph\": 1, \"nodes\": {
  \"r\": {\"type\": \"read\", \"params\": {\"path\": \"$SAMPLE/cornell/f0001_ref1024.exr\"}},
  \"w\": {\"type\": \"write\", \"params\": {\"path\": \"t.exr\"}, \"inputs\": {\"image\": \"r.albedo\"}}}}"
expect missing_feature_pass 1 "has no albedo pass" -- "$EW" graph run "$T/novector.json"
[ ! -e "$T/t.exr" ] && ok bad_graphs_write_nothing || bad bad_graphs_write_nothing

# ---- output safety
cp "$IN" "$T/in.exr"; sum=$(md5sum <"$T/in.exr")
graph overwrite.json '{"edgewise_graph": 1, "nodes": {
  "r": {"type": "read", "params": {"path": "in.exr"}},
  "d": {"type": "outlier", "inputs": {"color": "r.color"}},
  "w": {"type": "write", "params": {"path": "in.exr"}, "inputs": {"image": "d"}}}}'
expect overwrite_input_refused 1 "refusing to write" -- "$EW" graph run "$T/overwrite.json"
ln -s in.exr "$T/alias.exr"
expect overwrite_via_link_refused 1 "it is an input of the graph" -- "$EW" graph run "$T/overwrite.json" --set w.path="$T/alias.exr"
[ "$(md5sum <"$T/in.exr")" = "$sum" ] && ok input_untouched || bad input_untouched
expect missing_output_dir 1 "does not exist" -- "$EW" graph run "$T/overwrite.json" --set w.path="$T/no/dir/o.exr"
mkdir -p "$T/mid"; mkdir "$T/mid/out_0002.png"   # frame 2's output cannot be written
graph mid.json '{"edgewise_graph": 1, "nodes": {
  "r": {"type": "read", "params": {"path": "seq/render_####.exr"}},
  "w": {"type": "write", "params": {"path": "mid/out_####.png"}, "inputs": {"image": "r.color"}}}}'
expect unwritable_mid_sequence 1 "node 'w': frame 2:" -- "$EW" graph run "$T/mid.json"
[ -s "$T/mid/out_0001.png" ] && [ ! -e "$T/mid/out_0003.png" ] && ok earlier_frames_kept || bad earlier_frames_kept
if ls -A "$T/mid" | grep -q tmp; then bad no_temporaries_left; else ok no_temporaries_left; fi

finish
