#!/usr/bin/env bash
# Installs dependencies, builds gsd (Release, warnings as errors) and runs every test.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup-deps.sh
bash scripts/build.sh -DGSD_WERROR=ON -DGSD_BUILD_TESTS=ON
export XDG_RUNTIME_DIR=${XDG_RUNTIME_DIR:-/tmp}
ctest --test-dir build --output-on-failure --timeout 1800 "$@"
