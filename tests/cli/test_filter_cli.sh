#!/usr/bin/env bash
# `edgewise filter` and `edgewise dof` on good and bad input. Usage:
#   test_filter_cli.sh EDGEWISE_BIN MAKE_FIXTURES_BIN WEIGHTS_FILE
# Prints "N passed, N failed" and exits non-zero on any failure.
set -u
EW="$1"; FIX="$2"; WEIGHTS="$3"
. "$(dirname "$0")/../lib/harness.sh"
EXPECT_WHERE="err out" # some answers (--help, info) are on stdout


"$FIX" "$T" || { echo "0 passed, 1 failed"; exit 1; }
IN="$T/two_layers.exr"   # layers 'Back Plate' (colour) and 'ViewLayer' (colour, normal, Denoising Depth)

# ---- help and usage errors
"$EW" --help | grep -q "filter IN -o OUT" && ok help_lists_filter || bad help_lists_filter
"$EW" --help | grep -q "dof IN -o OUT" && ok help_lists_dof || bad help_lists_dof
"$EW" filter --help | grep -q -- "--sigma-spatial" && ok filter_help || bad filter_help
"$EW" dof --help | grep -q -- "--focus-distance" && ok dof_help || bad dof_help
expect filter_no_input 2 "needs an input" -- "$EW" filter
expect filter_no_output 2 "-o OUT" -- "$EW" filter "$IN"
expect filter_bad_method 2 "unknown --method 'median'" -- "$EW" filter "$IN" -o "$T/o.exr" --method median
expect filter_bad_model 2 "unknown --model 'fancy'" -- "$EW" filter "$IN" -o "$T/o.exr" --model fancy
expect filter_bad_radius 2 "--radius expects an integer in [0, 256]" -- "$EW" filter "$IN" -o "$T/o.exr" --radius 300
expect dof_no_output 2 "-o OUT" -- "$EW" dof "$IN"
expect dof_focus_in_lens 1 "'focus_distance' = 0.02 m is not beyond the focal length" -- "$EW" dof "$IN" -o "$T/o.exr" --layer ViewLayer --focus-distance 0.02
expect filter_param_of_another_method 2 "filter 'atrous' has no parameter --model" -- "$EW" filter "$IN" -o "$T/o.exr" --method atrous --model gi
expect filter_library_range 2 "--sigma-normal expects a number in [0, 100]" -- "$EW" filter "$IN" -o "$T/o.exr" --method atrous --sigma-normal 500
no_file "$T/o.exr" usage_errors_write_nothing

# ---- bad input
expect filter_missing_file 1 "cannot read '$T/nope.exr'" -- "$EW" filter "$T/nope.exr" -o "$T/o.exr"
expect filter_output_is_input 1 "refusing to write the output over the input" -- "$EW" filter "$IN" -o "$IN"
expect filter_unknown_pass 1 "has no pass 'Emit'" -- "$EW" filter "$IN" -o "$T/o.exr" --pass Emit
expect filter_gi_without_features 1 "model' = gi (GI denoising) needs a 'normal' and/or a 'depth' image" -- "$EW" filter "$IN" -o "$T/o.exr" --model gi --layer "Back Plate"
expect filter_no_colour 1 "no colour pass" -- "$EW" filter "$T/depth_only.exr" -o "$T/o.exr"
echo "garbage" >"$T/bad.ewpw"
expect filter_bad_weights_file 1 "--weights '$T/bad.ewpw': data 'weights': not a pyramid weights file" -- "$EW" filter "$IN" -o "$T/o.exr" --weights "$T/bad.ewpw"
expect dof_no_depth 1 "has no depth pass (looked for Depth and Denoising Depth)" -- "$EW" dof "$T/no_albedo.exr" -o "$T/o.exr"
no_file "$T/o.exr" bad_inputs_write_nothing

# ---- filtering
expect radius_0 0 "" -- "$EW" filter "$IN" -o "$T/r0.exr" -q --radius 0
"$EW" compare "$T/r0.exr" "$IN" | grep -q "PSNR inf" && ok radius_0_is_identity || bad radius_0_is_identity
for m in pyramid bilateral separable atrous; do
  expect "method_$m" 0 "wrote $T/$m.exr" -- "$EW" filter "$IN" -o "$T/$m.exr" --method "$m" --radius 6
done
"$EW" compare "$T/pyramid.exr" "$IN" | grep -Eq "PSNR [0-9.]+ dB" && ok filtering_changes_the_image || bad filtering_changes_the_image
"$EW" info "$T/pyramid.exr" | grep -q "layer 'ViewLayer'" && ok output_keeps_other_layers || bad output_keeps_other_layers
expect model_gi 0 "normal, depth; model gi, radius 8," -- "$EW" filter "$IN" -o "$T/gi.exr" --layer ViewLayer --model gi
expect model_depth_on_depth 0 "'Denoising Depth'" -- "$EW" filter "$IN" -o "$T/dz.exr" --layer ViewLayer --pass "Denoising Depth" --model depth
expect model_color_guide 0 "" -- "$EW" filter "$IN" -o "$T/g.exr" --layer ViewLayer --guide-pass "Denoising Albedo" --sigma-range 0.05
expect weights_analytic 0 "" -- "$EW" filter "$IN" -o "$T/a.exr" --weights analytic --radius 20
if [ -f "$WEIGHTS" ]; then
  expect weights_file 0 "" -- "$EW" filter "$IN" -o "$T/wf.exr" --weights "$WEIGHTS" --radius 20
  "$EW" compare "$T/wf.exr" "$T/a.exr" | grep -Eq "PSNR [0-9.]+ dB" && ok trained_differs_from_analytic || bad trained_differs_from_analytic
fi
expect png_output_and_reference 0 "-> output PSNR" -- "$EW" filter "$IN" -o "$T/o.png" --radius 4 --reference "$IN"
[ -s "$T/o.png" ] && ok png_written || bad png_written

# ---- depth of field (two_layers' ViewLayer has Denoising Depth: 5 left, 1.5 right)
expect dof_runs 0 "dof 'coc' (pass 'CoC') ranges from -" -- "$EW" dof "$IN" -o "$T/dof.exr" --layer ViewLayer --focus-distance 5 --fstop 1.4 --coc-pass CoC
"$EW" info "$T/dof.exr" | grep -q "ViewLayer.CoC.Z" && ok dof_writes_coc_pass || bad dof_writes_coc_pass
expect dof_exact_with_reference 0 "-> output PSNR" -- "$EW" dof "$IN" -o "$T/dofx.exr" --layer ViewLayer --focus-distance 5 --method bilateral --reference "$IN"

# every filter of the library is a --method, with its own parameters in the help
for m in $("$EW" nodes --json 2>/dev/null | python3 -c 'import json,sys; print(" ".join(json.load(sys.stdin)["filter"]["params"][0]["choices"]))' 2>/dev/null); do
  "$EW" filter --help | grep -q -- "--method $m:" && ok "help_lists_$m" || bad "help_lists_$m"
done
expect dof_method_by_name 0 "method separable" -- "$EW" dof "$IN" -o "$T/dofs.exr" --layer ViewLayer --focus-distance 5 --method separable
expect dof_method_unknown 2 "unknown --method 'fast' (pyramid, bilateral, separable" -- "$EW" dof "$IN" -o "$T/o2.exr" --method fast

finish
