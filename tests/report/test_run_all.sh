#!/bin/sh
# bench/run_all.sh -n (the commands it would run) from a copied checkout whose
# build directory was configured for the original: no re-configuration, the
# strips directory made, -d passed on to the stability suite, -q smaller.
# Usage: test_run_all.sh RUN_ALL_SH
set -u
# the build directory the copy names, not the one of the suite running this
# (tools/test.sh exports EW_BUILD_DIR, e.g. build-asan in CI)
unset EW_BUILD_DIR
RUN_ALL=$1
. "$(dirname "$0")/../lib/harness.sh"

# a copied checkout: the script, and a build directory configured elsewhere
mkdir -p "$T/copy/bench" "$T/copy/build/bin" "$T/data" "$T/original"
cp "$RUN_ALL" "$T/copy/bench/run_all.sh"
echo "CMAKE_HOME_DIRECTORY:INTERNAL=$T/original" >"$T/copy/build/CMakeCache.txt"
for b in edgewise bench_filters test_stability train_nbg; do printf '#!/bin/sh\n' >"$T/copy/build/bin/$b"; chmod +x "$T/copy/build/bin/$b"; done

sh "$T/copy/bench/run_all.sh" -n -d "$T/data" -o "$T/out" >"$T/out.txt" 2>"$T/err"; rc=$?
[ $rc -eq 0 ] && ok dry_run_succeeds || bad "dry_run_succeeds (exit $rc)"
! grep -q "cmake" "$T/err" && grep -q "configured for $T/original" "$T/err" && ok copied_build_not_reconfigured \
  || bad copied_build_not_reconfigured
grep -q "mkdir' '-p' '$T/out/strips'" "$T/err" && ok strips_directory_made || bad strips_directory_made
grep -q "EW_SHARED_DATA='$T/data' EW_STABILITY_STRIPS='$T/out/strips'" "$T/err" && ok data_passed_to_stability \
  || bad data_passed_to_stability
[ ! -e "$T/out" ] && ok dry_run_writes_nothing || bad dry_run_writes_nothing

sh "$T/copy/bench/run_all.sh" -n -q -d "$T/data" -o "$T/out" >"$T/q.txt" 2>"$T/err"
full=$(grep -c "" "$T/err")
grep "'bench'" "$T/err" | head -1 | grep -q "'--spp' '1,4'" && grep -q "'--quick'" "$T/err" \
  && ! grep -q "nbg-7layer" "$T/err" && ok quick_is_smaller || bad quick_is_smaller

# a build directory of this checkout is brought up to date, not re-configured
echo "CMAKE_HOME_DIRECTORY:INTERNAL=$T/copy" >"$T/copy/build/CMakeCache.txt"
sh "$T/copy/bench/run_all.sh" -n -d "$T/data" -o "$T/out" >/dev/null 2>"$T/err"
grep -q "'cmake' '--build'" "$T/err" && ! grep -q "'cmake' '-S'" "$T/err" && ok own_build_updated || bad own_build_updated

finish
