#!/usr/bin/env bash
# The test suite under AddressSanitizer + UndefinedBehaviorSanitizer (clang), then a short,
# reproducible fuzz run over every reader, then the CLI mutation campaign (the regression inputs
# of tests/data/cli-regressions/ and ~4,000 seeded mutants through every command that reads a
# file: scripts/cli-campaign.sh). scripts/test.sh runs it after the Release suite.
#
#   scripts/sanitize.sh [FUZZ_RUNS]      inputs per fuzz target (default 20000; 0: no fuzz run)
#   scripts/sanitize.sh 0 -R test_io     extra arguments go to ctest
#   GSD_CLI_CAMPAIGN=0 scripts/sanitize.sh    without the CLI campaign
#
# Build: build-san/ (scripts/sanitizer-build.sh). Leak checking is on everywhere. Lavapipe, the
# CPU Vulkan driver, is unloaded at exit before LeakSanitizer looks, which would make a block it
# keeps in a global look leaked from "<unknown module>"; tests/sanitizers/keep_loaded.c, preloaded,
# keeps every library mapped instead, so nothing needs suppressing (docs/io.md, "Sanitizers").
set -euo pipefail
cd "$(dirname "$0")/.."
root=$PWD
runs=${1:-20000}
[[ $runs =~ ^[0-9]+$ ]] || { echo "usage: scripts/sanitize.sh [FUZZ_RUNS] [ctest arguments]" >&2; exit 2; }
[ $# -gt 0 ] && shift

bash scripts/sanitizer-build.sh
cc -O2 -shared -fPIC -o build-san/keep_loaded.so tests/sanitizers/keep_loaded.c

start=$SECONDS
(
  export ASAN_OPTIONS="detect_leaks=1:abort_on_error=0:symbolize=1:check_initialization_order=1"
  export UBSAN_OPTIONS="print_stacktrace=1:halt_on_error=1"
  export LD_PRELOAD=$root/build-san/keep_loaded.so
  export XDG_RUNTIME_DIR=${XDG_RUNTIME_DIR:-/tmp}
  ctest --test-dir build-san --output-on-failure --timeout 3000 "$@"
)
echo "sanitize: test suite took $((SECONDS - start)) s"

if [ "$runs" -gt 0 ]; then
  start=$SECONDS
  FUZZ_RUNS=$runs bash scripts/fuzz.sh
  echo "sanitize: fuzz run took $((SECONDS - start)) s"
fi

if [ "${GSD_CLI_CAMPAIGN:-1}" != 0 ]; then
  start=$SECONDS
  bash scripts/cli-campaign.sh
  echo "sanitize: CLI campaign took $((SECONDS - start)) s"
fi
