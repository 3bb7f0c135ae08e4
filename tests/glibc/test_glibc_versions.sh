#!/bin/sh
# The glibc a binary needs is the newest GLIBC_x.y symbol version it imports.
# Lists them for libedgewise and the OFX bundle and fails when one is newer
# than the floor this build promises (docs/portability.md). Also builds a
# small program through cmake/glibc_compat.h to show the pinning works here.
# Usage: test_glibc_versions.sh FLOOR COMPAT_HEADER CC FILE...
set -u
FLOOR=$1; HEADER=$2; CC=$3; shift 3
command -v objdump >/dev/null || { echo "skipped: no objdump"; exit 77; }
ldd --version 2>&1 | head -1 | grep -qi "glibc\|gnu libc" || { echo "skipped: not glibc"; exit 77; }
. "$(dirname "$0")/../lib/harness.sh"
newer() { # A > B as versions
  [ "$(printf '%s\n%s\n' "$1" "$2" | sort -V | tail -1)" = "$1" ] && [ "$1" != "$2" ]
}
versions() { objdump -T "$1" | sed -n 's/.*(GLIBC_\([0-9.]*\)).*/\1/p' | sort -uV; }

for f in "$@"; do
  [ -f "$f" ] || { bad "missing $f"; continue; }
  top=$(versions "$f" | tail -1)
  echo "     $(basename "$f"): GLIBC $(versions "$f" | tr '\n' ' ')"
  if newer "$top" "$FLOOR"; then
    bad "$(basename "$f") needs glibc $top, newer than the floor $FLOOR:"
    objdump -T "$f" | grep "GLIBC_" | while read -r line; do
      v=$(echo "$line" | sed -n 's/.*(GLIBC_\([0-9.]*\)).*/\1/p')
      newer "$v" "$FLOOR" && echo "       $line"
    done
  else
    ok "$(basename "$f") needs glibc $top (floor $FLOOR)"
  fi
done

# the pinning itself: a program using what libedgewise uses, built both ways
cat >"$T/p.c" <<'EOC'
#include <dlfcn.h>
#include <math.h>
#include <pthread.h>
#include <stdio.h>
static void *run(void *a) { return a; }
static void init(void) {}
int main(int argc, char **argv) {
    (void)argv;
    pthread_t t;
    pthread_once_t once = PTHREAD_ONCE_INIT;
    pthread_key_t k;
    pthread_key_create(&k, NULL);
    pthread_setspecific(k, &t);
    pthread_once(&once, init);
    pthread_create(&t, NULL, run, NULL);
    pthread_join(t, NULL);
    void *h = dlopen(argc > 99 ? "x" : NULL, RTLD_NOW);
    if (h) dlclose(h);
    volatile double x = argc;
    printf("%g %g %g %g %g\n", exp(x), exp2(x), log(x + 1), log2(x + 1), pow(x, 0.5));
    return 0;
}
EOC
if "$CC" -O1 -o "$T/plain" "$T/p.c" -lm -lpthread -ldl 2>"$T/err" && \
   "$CC" -O1 -include "$HEADER" -o "$T/pinned" "$T/p.c" -Wl,--no-as-needed -lm -lpthread -ldl 2>>"$T/err"; then
  echo "     plain: GLIBC $(versions "$T/plain" | tr '\n' ' ')"
  echo "     with glibc_compat.h: GLIBC $(versions "$T/pinned" | tr '\n' ' ')"
  # __libc_start_main comes from crt1.o, in executables only: libraries never import it
  top=$(objdump -T "$T/pinned" | grep -v __libc_start_main | sed -n 's/.*(GLIBC_\([0-9.]*\)).*/\1/p' | sort -uV | tail -1)
  newer "$top" "2.28" && bad "glibc_compat.h leaves GLIBC_$top" || ok "glibc_compat.h pins to $top <= 2.28"
  [ "$("$T/plain" 1)" = "$("$T/pinned" 1)" ] && ok pinned_functions_same_results || bad pinned_functions_same_results
else
  bad "cannot build the pinning check: $(cat "$T/err")"
fi
finish
