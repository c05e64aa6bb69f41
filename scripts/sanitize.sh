#!/usr/bin/env bash
# The fast label of the test suite under AddressSanitizer + UndefinedBehaviorSanitizer (clang), two
# tests at a time (every suite has cases there: docs/testing.md), then a short,
# reproducible fuzz run over every reader, then the CLI mutation campaign (the regression inputs
# of tests/data/cli-regressions/ and ~4,000 seeded mutants through every command that reads a
# file: scripts/cli-campaign.sh). scripts/test.sh runs it after the Release suite.
#
#   scripts/sanitize.sh [FUZZ_RUNS]      inputs per fuzz target (default 20000; 0: no fuzz run)
#   scripts/sanitize.sh 0 -R test_io     extra arguments go to ctest
#   scripts/sanitize.sh 0 -LE nothing    every label (the slow cases too: about 25 minutes more)
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

source scripts/phases.sh
trap phases_summary EXIT
phase "sanitizer build" bash scripts/sanitizer-build.sh
cc -O2 -shared -fPIC -o build-san/keep_loaded.so tests/sanitizers/keep_loaded.c

labels=(-L fast)  # unless the arguments choose labels themselves
for a in "$@"; do [[ $a == -L* ]] && labels=(); done
sanitized_suite() (
  export ASAN_OPTIONS="detect_leaks=1:abort_on_error=0:symbolize=1:check_initialization_order=1"
  export UBSAN_OPTIONS="print_stacktrace=1:halt_on_error=1"
  export LD_PRELOAD=$root/build-san/keep_loaded.so
  export XDG_RUNTIME_DIR=${XDG_RUNTIME_DIR:-/tmp}
  ctest --test-dir build-san --output-on-failure --timeout 3000 -j "$(nproc)" "${labels[@]}" "$@"
)
phase "sanitized suite (${labels[*]:-as asked})" sanitized_suite "$@"

if [ "$runs" -gt 0 ]; then
  FUZZ_RUNS=$runs phase "fuzz ($runs inputs per reader)" bash scripts/fuzz.sh
fi

if [ "${GSD_CLI_CAMPAIGN:-1}" != 0 ]; then
  phase "CLI campaign" bash scripts/cli-campaign.sh
fi
