#!/usr/bin/env bash
# Benchmarks: PAT fit and evaluation throughput, CPU vs GPU side by side, and the accuracy
# table on the analytic shapes. Extra arguments go to gsd-bench
# (e.g. --sizes 10000,100000 --queries 100000 --devices cpu,gpu).
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup-deps.sh
bash scripts/build.sh >/dev/null
export XDG_RUNTIME_DIR=${XDG_RUNTIME_DIR:-/tmp}
echo "== machine: $(nproc) cores; $(build/bin/gsd info | grep -- '--device gpu')"
build/bin/gsd-bench "$@"
echo
build/bin/gsd-accuracy --grid 64
