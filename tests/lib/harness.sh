# The shell tests' common part, sourced (POSIX sh) by each script after its
# arguments are read: a scratch directory $T removed at exit, the pass/fail
# count, and the checks they share. A script ends with `finish`, which prints
# "N passed, N failed" and exits non-zero on any failure.
T=$(mktemp -d) || exit 1
trap 'rm -rf "$T"' EXIT
pass=0
fail=0

ok() { pass=$((pass + 1)); echo "ok   $1"; }

# A failure, with the stderr of the command the check ran (expect, or a
# script's own command writing $T/err).
bad() {
  fail=$((fail + 1))
  echo "FAIL $1"
  if [ -s "$T/err" ]; then sed 's/^/     stderr: /' "$T/err" | head -40; fi
}

# expect NAME EXIT_CODE SUBSTRING -- COMMAND ARGS...
# The command's exit code; SUBSTRING (when not empty) in what it printed
# ($EXPECT_WHERE: err, or "err out"); on failure exactly one line on stderr
# (unless EXPECT_ONE_LINE=0). With EXPECT_TIMEOUT=S the command is stopped
# after S seconds (a blocking open must fail, not hang).
expect() {
  _name=$1 _code=$2 _want=$3
  shift 4
  if [ -n "${EXPECT_TIMEOUT:-}" ]; then
    timeout "$EXPECT_TIMEOUT" "$@" >"$T/out" 2>"$T/err"
  else
    "$@" >"$T/out" 2>"$T/err"
  fi
  _got=$?
  if [ "$_got" -ne "$_code" ]; then bad "$_name (exit $_got, expected $_code)"; return; fi
  if [ -n "$_want" ]; then
    _found=0
    for _s in ${EXPECT_WHERE:-err}; do
      grep -qF -- "$_want" "$T/$_s" && _found=1
    done
    if [ "$_found" -eq 0 ]; then bad "$_name (${EXPECT_WHERE:-err} lacks '$_want')"; return; fi
  fi
  if [ "$_code" -ne 0 ] && [ "${EXPECT_ONE_LINE:-1}" -eq 1 ] && [ "$(wc -l <"$T/err")" -ne 1 ]; then
    bad "$_name (expected one line on stderr)"
    return
  fi
  ok "$_name"
}

# no_file PATH NAME: nothing at PATH (a refused run wrote nothing).
no_file() { if [ -e "$1" ]; then bad "$2: $1 exists"; else ok "$2"; fi; }

# no_temps DIR NAME [PATTERN]: no temporary (a name matching PATTERN,
# default 'tmp') left in DIR.
no_temps() { if ls -A "$1" | grep -q -- "${3:-tmp}"; then bad "$2: temporary left in $1"; else ok "$2"; fi; }

finish() {
  echo "$pass passed, $fail failed"
  [ "$fail" -eq 0 ] && exit 0
  exit 1
}
