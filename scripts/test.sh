#!/usr/bin/env bash
# Installs dependencies, builds gsd (Release, warnings as errors) and runs every test; then the
# same suite under AddressSanitizer + UBSan (clang), a short reproducible fuzz run over every
# reader and the CLI mutation campaign (scripts/sanitize.sh; GSD_SANITIZE=0 skips that part).
# Arguments go to the Release ctest.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup-deps.sh
bash scripts/build.sh -DGSD_WERROR=ON -DGSD_BUILD_TESTS=ON -DGSD_PYTHON=ON
export XDG_RUNTIME_DIR=${XDG_RUNTIME_DIR:-/tmp}
ctest --test-dir build --output-on-failure --timeout 1800 "$@"
if [ "${GSD_SANITIZE:-1}" != 0 ]; then
  bash scripts/sanitize.sh
fi
