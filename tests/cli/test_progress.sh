#!/usr/bin/env bash
# A progress bar on a terminal (denoise, filter, dof, graph run: percent,
# frame N/M, time), nothing when stderr is not a terminal or with -q.
# Usage: test_progress.sh EDGEWISE_BIN SAMPLE_DIR
set -u
EW="$1"; SAMPLE=$(cd "$2" && pwd)
. "$(dirname "$0")/../lib/harness.sh"
if ! command -v script >/dev/null; then echo "skipped: no 'script' to run under a terminal"; exit 77; fi
IN="$SAMPLE/cornell/f0001_spp0004.exr"

# run under a pseudo-terminal; everything it printed lands in $2
on_tty() { local out="$1"; shift; script -qec "$*" /dev/null >"$out" 2>&1 </dev/null; }

on_tty "$T/d.tty" "'$EW' denoise '$IN' -o '$T/d.exr'"
grep -q 'denoise .ViewLayer. \[#*\.*\] *[0-9]*%' "$T/d.tty" && grep -q '100%' "$T/d.tty" && ok denoise_bar_on_tty \
  || { bad denoise_bar_on_tty; cat -v "$T/d.tty" | head -5; }
on_tty "$T/f.tty" "'$EW' filter '$IN' -o '$T/f.exr'"
grep -q 'pyramid \[#' "$T/f.tty" && ok filter_bar_on_tty || { bad filter_bar_on_tty; cat -v "$T/f.tty" | head -5; }
on_tty "$T/o.tty" "'$EW' dof '$IN' -o '$T/o.exr'"
grep -q 'dof \[#' "$T/o.tty" && ok dof_bar_on_tty || { bad dof_bar_on_tty; cat -v "$T/o.tty" | head -5; }

mkdir -p "$T/seq"
for f in 1 2 3; do cp "$IN" "$T/seq/render_000$f.exr"; done
cat >"$T/g.json" <<EOF
{"edgewise_graph": 1, "nodes": {
  "r": {"type": "read", "params": {"path": "$T/seq/render_####.exr"}},
  "d": {"type": "denoise", "params": {"method": "bgrid"}, "inputs": {"color": "r.noisy", "albedo": "r.albedo"}},
  "w": {"type": "write", "params": {"path": "$T/seq/out_####.exr"}, "inputs": {"image": "d"}}}}
EOF
on_tty "$T/g.tty" "'$EW' graph run '$T/g.json'"
grep -q 'graph \[.*frame 2/3' "$T/g.tty" && grep -q 'frame 3/3' "$T/g.tty" && ok graph_bar_counts_frames \
  || { bad graph_bar_counts_frames; cat -v "$T/g.tty" | head -5; }
grep -q '^frame 3:' "$T/g.tty" && ok graph_summary_still_printed || bad graph_summary_still_printed

# quiet: with -q on a terminal, and whenever stderr is a file or a pipe
on_tty "$T/q.tty" "'$EW' denoise '$IN' -o '$T/q.exr' -q"
[ ! -s "$T/q.tty" ] && ok quiet_on_tty || { bad quiet_on_tty; cat -v "$T/q.tty" | head -3; }
"$EW" denoise "$IN" -o "$T/p.exr" 2>"$T/p.err"
! grep -q '%' "$T/p.err" && ! grep -q $'\r' "$T/p.err" && ok no_bar_when_not_a_tty || bad no_bar_when_not_a_tty
"$EW" graph run "$T/g.json" 2>"$T/g.err" >/dev/null
! grep -q '\[#' "$T/g.err" && ok graph_no_bar_when_not_a_tty || bad graph_no_bar_when_not_a_tty

finish
