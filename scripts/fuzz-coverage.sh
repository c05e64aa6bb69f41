#!/usr/bin/env bash
# Line coverage of the readers under the fuzz corpora: builds the fuzz targets with clang's
# source-based coverage into build-cov/ (no Vulkan: the readers do not touch it), runs each
# target once over its inputs (no fuzzing: -runs=0), and prints llvm-cov's per-file report for
# the files that parse input. Inputs: fuzz/corpus/<target>/, the seeds and corpus that
# scripts/fuzz.sh left in build-san/, and DIR/<target>/ for each DIR in $FUZZ_COVERAGE_CORPUS
# (colon-separated; e.g. a corpus from a longer campaign elsewhere).
#
#   scripts/fuzz-coverage.sh            (docs/io.md, "Fuzzing")
set -euo pipefail
cd "$(dirname "$0")/.."
build=build-cov
targets=(point_cloud mesh npy tori safetensors curve grid_metadata)
# What parses input: the readers, the .tori and .safetensors loaders, the curve files.
readers=(src/io/*.cpp src/pat/tori_file.cpp src/pat/safetensors.cpp)

bash scripts/setup-deps.sh clang libclang-rt-14-dev libomp-dev llvm
cov="-fprofile-instr-generate -fcoverage-mapping -fsanitize=fuzzer-no-link"
CC=clang CXX=clang++ cmake -S . -B $build -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo -DGSD_FUZZ=ON \
  -DGSD_BUILD_TESTS=OFF -DGSD_BUILD_TOOLS=OFF -DGSD_WITH_VULKAN=OFF -DGSD_PYTHON=OFF \
  "-DCMAKE_CXX_FLAGS_RELWITHDEBINFO=-O1 -g" "-DCMAKE_C_FLAGS_RELWITHDEBINFO=-O1 -g" \
  "-DCMAKE_CXX_FLAGS=$cov" "-DCMAKE_C_FLAGS=$cov" "-DCMAKE_EXE_LINKER_FLAGS=-fprofile-instr-generate" >/dev/null
cmake --build $build --parallel "$(nproc)" --target "${targets[@]/#/fuzz_}"

rm -rf $build/prof && mkdir -p $build/prof
export ASAN_OPTIONS="detect_leaks=0" OMP_NUM_THREADS=1
objects=()
for t in "${targets[@]}"; do
  inputs=()
  for d in fuzz/corpus/$t build-san/seeds/$t build-san/corpus/$t tests/data/fuzz-regressions/$t; do
    [ -d "$d" ] && inputs+=("$d")
  done
  IFS=: read -r -a extra <<< "${FUZZ_COVERAGE_CORPUS:-}"
  for d in "${extra[@]}"; do [ -d "$d/$t" ] && inputs+=("$d/$t"); done
  n=$(find "${inputs[@]}" -type f | wc -l)
  echo "fuzz-coverage: $t over $n inputs (${inputs[*]})"
  LLVM_PROFILE_FILE="$build/prof/$t.profraw" $build/bin/fuzz_$t -runs=0 "${inputs[@]}" >"$build/prof/$t.log" 2>&1
  objects+=(-object "$build/bin/fuzz_$t")
done
llvm-profdata merge -sparse $build/prof/*.profraw -o $build/prof/all.profdata
echo
echo "fuzz-coverage: line coverage of the readers (all targets' runs together)"
llvm-cov report "${objects[@]:1}" -instr-profile=$build/prof/all.profdata "${readers[@]}" | \
  awk '{ if (NR == 1 || /^-/ || /^TOTAL/ || /\.cpp/) print }' | sed "s|$PWD/||"
