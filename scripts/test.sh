#!/usr/bin/env bash
# The full check, and what CI runs (.ci/run): installs dependencies, builds gsd (Release, warnings
# as errors), runs every test (labels fast and slow) two at a time; then the fast label under
# AddressSanitizer + UBSan (clang), a short reproducible fuzz run over every reader and the CLI
# mutation campaign (scripts/sanitize.sh; GSD_SANITIZE=0 skips that part). Prints the time of each
# phase at the end. Arguments go to the Release ctest. The quick loop while editing is
# `ctest --test-dir build -L fast -j2` (docs/testing.md).
set -euo pipefail
cd "$(dirname "$0")/.."
source scripts/phases.sh
trap phases_summary EXIT

phase "dependencies" bash scripts/setup-deps.sh
phase "Release build" bash scripts/build.sh -DGSD_WERROR=ON -DGSD_BUILD_TESTS=ON -DGSD_PYTHON=ON
export XDG_RUNTIME_DIR=${XDG_RUNTIME_DIR:-/tmp}
phase "Release suite (all labels)" ctest --test-dir build --output-on-failure -j "$(nproc)" "$@"
if [ "${GSD_SANITIZE:-1}" != 0 ]; then
  bash scripts/sanitize.sh
fi
