#!/usr/bin/env bash
# Builds gsd with clang under AddressSanitizer + UndefinedBehaviorSanitizer into build-san/: the
# library (instrumented for libFuzzer's coverage too), the CLI, the tools, the test suites and the
# fuzz targets. Shared by scripts/sanitize.sh (the test suite) and scripts/fuzz.sh (the fuzzers).
#
#   scripts/sanitizer-build.sh [TARGET ...]      (no targets: everything)
#
# -O2 -g (at -O1 Eigen's small expressions are not inlined: the suite ran 1.4x slower) with
# assertions on (no NDEBUG; _GLIBCXX_ASSERTIONS checks std containers); UBSan findings abort
# instead of printing and going on; clang's warnings are errors, as gcc's are in build/.
set -euo pipefail
cd "$(dirname "$0")/.."
build=build-san

# ---- dependencies: the project's, plus clang with libFuzzer and its OpenMP runtime ------------
bash scripts/setup-deps.sh clang libclang-rt-14-dev libomp-dev

# Coverage for libFuzzer (-fsanitize=fuzzer-no-link) only on the code the fuzzers reach: fuzz/CMakeLists.txt.
san="-fsanitize=address,undefined -fno-sanitize-recover=undefined -fno-omit-frame-pointer"
# Configured every time (a few seconds), so a changed option here reaches an existing build-san/.
CC=clang CXX=clang++ cmake -S . -B $build -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo \
    -DGSD_FUZZ=ON -DGSD_BUILD_TESTS=ON -DGSD_BUILD_TOOLS=ON -DGSD_BUILD_BENCHMARKS=OFF -DGSD_WITH_VULKAN=ON -DGSD_WERROR=ON -DGSD_TESTS_SANITIZED=ON \
  "-DCMAKE_CXX_FLAGS_RELWITHDEBINFO=-O2 -g -D_GLIBCXX_ASSERTIONS" "-DCMAKE_C_FLAGS_RELWITHDEBINFO=-O2 -g" \
  "-DCMAKE_CXX_FLAGS=$san" "-DCMAKE_C_FLAGS=$san" >/dev/null
start=$SECONDS
if [ $# -gt 0 ]; then
  cmake --build $build --parallel "$(nproc)" --target "$@"
else
  cmake --build $build --parallel "$(nproc)"
fi
echo "sanitizer-build: build took $((SECONDS - start)) s"
