#!/usr/bin/env bash
# Every ELF the build made (programs, libraries, the CUDA module, the OFX
# plugin): an empty RUNPATH/RPATH entry ("a::b", a trailing ':') or a
# relative one makes the loader search the current directory, so a crafted
# libm.so.6 in the folder a user runs edgewise from would be loaded. Only
# absolute entries and $ORIGIN-based ones pass. Usage: test_runpath.sh BUILD_DIR
set -u
B="$1"
command -v readelf >/dev/null || { echo "skipped: no readelf"; exit 77; }
pass=0; fail=0; n=0
while IFS= read -r -d '' f; do
  head -c 4 "$f" 2>/dev/null | grep -q $'\x7fELF' || continue
  n=$((n+1))
  paths=$(readelf -d "$f" 2>/dev/null | sed -n 's/.*(\(RUNPATH\|RPATH\)).*\[\(.*\)\]/\2/p')
  [ -z "$paths" ] && continue
  while IFS= read -r p; do
    bad=""
    case "$p" in :*|*:|*::*) bad="empty entry" ;; esac
    IFS=: read -ra parts <<<"$p"
    for e in "${parts[@]}"; do
      case "$e" in /*|'$ORIGIN'|'$ORIGIN'/*) ;; "") bad="empty entry" ;; *) bad="relative entry '$e'" ;; esac
    done
    if [ -n "$bad" ]; then fail=$((fail+1)); echo "FAIL ${f#$B/}: [$p]: $bad"
    else pass=$((pass+1)); fi
  done <<<"$paths"
done < <(find "$B" -type f \( -perm -u+x -o -name '*.so*' -o -name '*.ofx' \) -not -path '*/CMakeFiles/*' -print0)
echo "$n ELF files, $pass run paths passed, $fail failed"
[ "$n" -gt 0 ] && [ "$fail" -eq 0 ]
