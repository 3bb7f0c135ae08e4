#!/usr/bin/env bash
# The benchmark's HTML page, checked in headless Chromium: a tiny bench (one
# committed stability scene, 1 spp, the input and two methods, with images),
# tools/bench_report.py, then Chromium loads a copy of index.html (same
# directory, so the same relative image paths) with a check script that runs
# on the load event and writes what it found into the DOM, which
# --dump-dom prints. Every <img> must have decoded (complete, naturalWidth >
# 0), and the page must hold the expected tables, rows and images. Then one
# image file is removed and the same check must report it as broken (so the
# check itself is shown to fail on a broken path, every run).
# Usage: test_report_browser.sh EDGEWISE_BIN BENCH_REPORT_PY DATA_DIR PYTHON3 CHROMIUM
# Exits 77 (skipped) without Chromium or a python3 with matplotlib.
set -u
EW="$1"; REPORT="$2"; DATA="$3"; PY="${4:-}"; CHROME="${5:-}"
SCENE=k_thin_1_64x64
METHODS=input,bgrid,auto        # the noisy input and two methods
N_METHODS=3
# charts (2) + per frame: one image per method and the reference, an error map per method
WANT_IMAGES=$((2 + N_METHODS + 1 + N_METHODS))
WANT_ROWS=2
WANT_TABLES=1

if [ -z "$CHROME" ] || ! "$CHROME" --version >/dev/null 2>&1; then
  echo "skipped: no chromium (Debian package chromium)"; exit 77
fi
if [ -z "$PY" ] || ! "$PY" -c "import matplotlib" >/dev/null 2>&1; then
  echo "skipped: no python3 with matplotlib (Debian package python3-matplotlib)"; exit 77
fi

. "$(dirname "$0")/../lib/harness.sh"

"$EW" bench "$DATA" -o "$T/out" --scenes "$SCENE" --spp 1 --methods "$METHODS" --repeat 1 --images \
  >"$T/bench.log" 2>&1 && ok bench || { bad bench; cat "$T/bench.log"; finish; }
"$PY" "$REPORT" "$T/out" >"$T/report.log" 2>&1 && [ -f "$T/out/index.html" ] && ok bench_report \
  || { bad "bench_report (no index.html)"; cat "$T/report.log"; finish; }

# A copy of the page with the check appended, next to index.html.
check_page() {
  sed 's#</body>#<script>\
window.addEventListener("load", function () {\
  var im = document.images, broken = [];\
  for (var i = 0; i < im.length; i++)\
    if (!im[i].complete || !(im[i].naturalWidth > 0)) broken.push(im[i].getAttribute("src"));\
  var p = document.createElement("pre");\
  p.textContent = "EWCHECK images=" + im.length + " broken=" + broken.length +\
    " rows=" + document.querySelectorAll("table tr").length +\
    " tables=" + document.querySelectorAll("table").length +\
    " h2=" + document.querySelectorAll("h2").length + " first_broken=" + (broken[0] || "-") + " EWEND";\
  document.body.appendChild(p);\
});\
</script></body>#' "$T/out/index.html" >"$T/out/check.html"
  grep -q EWCHECK "$T/out/check.html"
}

# Runs Chromium on check.html; prints the EWCHECK line ("" if the script did not run).
run_chrome() {
  local prof; prof=$(mktemp -d "$T/profile.XXXXXX")
  timeout 120 "$CHROME" --headless --no-sandbox --disable-gpu --disable-quic --no-first-run \
    --disable-background-networking --disable-component-update --disable-sync --disable-dev-shm-usage \
    --user-data-dir="$prof" --virtual-time-budget=10000 --dump-dom "file://$T/out/check.html" \
    >"$T/dom.html" 2>"$T/chrome.err"
  grep -o 'EWCHECK[^<]*EWEND' "$T/dom.html" | head -1
}

check_page && ok check_page || { bad "check_page (no </body> in index.html)"; finish; }
res=$(run_chrome)
echo "     chromium: ${res:-no result}"
if [ -z "$res" ]; then
  bad "chromium ran the check (no EWCHECK in the dumped DOM)"; sed 's/^/     chromium: /' "$T/chrome.err" | tail -5
else
  ok "chromium ran the check"
  case "$res" in *" broken=0 "*) ok all_images_decoded ;; *) bad "all_images_decoded: $res" ;; esac
  case "$res" in *" images=$WANT_IMAGES "*) ok "images=$WANT_IMAGES" ;; *) bad "expected $WANT_IMAGES images: $res" ;; esac
  case "$res" in *" rows=$WANT_ROWS "*) ok "rows=$WANT_ROWS" ;; *) bad "expected $WANT_ROWS table rows: $res" ;; esac
  case "$res" in *" tables=$WANT_TABLES "*) ok "tables=$WANT_TABLES" ;; *) bad "expected $WANT_TABLES table: $res" ;; esac
fi
# Every image file the bench wrote for the page is really referenced by it.
n_png=$(ls "$T/out/img" | grep -c '\.png$')
[ "$n_png" -eq $((WANT_IMAGES - 2)) ] && ok "bench wrote $n_png images" || bad "bench wrote $n_png images, expected $((WANT_IMAGES - 2))"

# The check must catch a broken image path: remove one image and look again.
victim=$(ls "$T/out/img" | grep '_err\.png$' | head -1)
rm -f "$T/out/img/$victim"
res=$(run_chrome)
echo "     chromium with img/$victim removed: ${res:-no result}"
case "$res" in
  *" broken=1 "*"first_broken=img/$victim "*) ok detects_broken_image ;;
  *) bad "detects_broken_image: $res" ;;
esac
finish
