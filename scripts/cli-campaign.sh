#!/usr/bin/env bash
# The CLI mutation campaign (tools/fuzz/mutate_cli.py) against the ASan+UBSan gsd in build-san/:
# first the regression inputs of tests/data/cli-regressions/ (replayed every run), then mutants
# of every input format through every command that reads it, each run in an empty folder with a
# time limit (20 s of CPU time, which a loaded machine does not move; 60 s of wall time for a run
# that waits without computing) and a memory cap (GSD_MEMORY_LIMIT=1G, peak RSS 2 GiB).
#
#   scripts/cli-campaign.sh                       CI's campaign: seed 1, CI_COUNTS below (~4 min, 2 cores)
#   scripts/cli-campaign.sh --minutes 30 --seed 9001      any mutate_cli.py options instead
#
# scripts/sanitize.sh (so CI) runs it after the fuzz targets; `FUZZ_TARGETS=cli scripts/fuzz.sh
# 900` runs a longer one. Exits 1 on a finding (each printed with its reproducer: rerun that one
# mutant with `--index`; copies under build-san/cli-findings/), 2 on a setup error.
# docs/io.md, "Mutation campaigns".
set -euo pipefail
cd "$(dirname "$0")/.."
root=$PWD

# Mutants per format in CI (names or prefixes, tools/fuzz/mutate_cli.py --list-formats): 4,020
# runs, about 3 minutes on 2 cores. Meshes and clouds get most: their commands do the geometry.
CI_COUNTS="mesh=300,cloud=200,queries-npy=150,grid-npy=150,grid-sidecar=100,tori=200,\
safetensors=80,curve=120,points-txt=80"

bash scripts/sanitizer-build.sh gsd_cli
# The .vdb plugin is not a dependency of gsd_cli's link (a module loaded at run time): build it
# where OpenVDB was found, or the campaign writes those grids as .npy instead.
if ninja -C build-san -t targets all 2>/dev/null | grep -q '^gsd_vdb:'; then
  cmake --build build-san --target gsd_vdb >/dev/null
fi
cc -O2 -shared -fPIC -o build-san/keep_loaded.so tests/sanitizers/keep_loaded.c

export GSD_KEEP_LOADED=$root/build-san/keep_loaded.so  # (docs/io.md, "Sanitizers")
export XDG_RUNTIME_DIR=${XDG_RUNTIME_DIR:-/tmp}
rm -rf build-san/cli-findings
args=(--count 0 --counts "$CI_COUNTS" --seed 1)
[ $# -gt 0 ] && args=("$@")
# One run per core: nproc without OMP_NUM_THREADS, which it honours (scripts/fuzz.sh sets it to 1).
jobs=$(env -u OMP_NUM_THREADS -u OMP_THREAD_LIMIT nproc)
exec python3 tools/fuzz/mutate_cli.py --gsd build-san/bin/gsd --regressions tests/data/cli-regressions \
  --jobs "$jobs" --cpu-timeout 20 --timeout 60 --keep-findings build-san/cli-findings "${args[@]}"
