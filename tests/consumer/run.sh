#!/usr/bin/env bash
# Installs the built gsd into a scratch prefix and builds a separate project against it, twice:
# through CMake (find_package) and through pkg-config. Checks that libgsd exports no vk* symbol.
#   tests/consumer/run.sh BUILD_DIR
set -euo pipefail
build=$(cd "$1" && pwd)
here=$(cd "$(dirname "$0")" && pwd)
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
prefix=$work/prefix

cmake --install "$build" --prefix "$prefix" >/dev/null
lib=$(ls "$prefix"/lib/*/libgsd.so "$prefix"/lib/libgsd.so 2>/dev/null | head -1 || true)
archive=$(ls "$prefix"/lib/*/libgsd.a "$prefix"/lib/libgsd.a 2>/dev/null | head -1 || true)
# Neither library may define a vk* or volk* symbol an application's loader could collide with.
if [ -n "$lib" ]; then
  if nm -D --defined-only "$lib" | awk '{print $NF}' | grep -E '^(vk|volk)' ; then
    echo "FAIL: libgsd.so exports vk*/volk* symbols (above)"; exit 1
  fi
  echo "ok: libgsd.so exports $(nm -D --defined-only "$lib" | wc -l) symbols, no vk*/volk*"
fi
if [ -n "$archive" ]; then
  if nm --defined-only "$archive" 2>/dev/null | awk 'NF == 3 && $2 ~ /[A-Z]/ {print $3}' | grep -E '^(vk|volk)' ; then
    echo "FAIL: libgsd.a defines global vk*/volk* symbols (above)"; exit 1
  fi
  echo "ok: libgsd.a defines no global vk*/volk* symbol"
fi

# The .vdb plugin, when it was built, is installed beside the library that loads it.
if [ -e "$build/lib/libgsd_vdb.so" ]; then
  plugin=$(ls "$prefix"/lib/*/libgsd_vdb.so "$prefix"/lib/libgsd_vdb.so 2>/dev/null | head -1 || true)
  [ -n "$plugin" ] || { echo "FAIL: libgsd_vdb.so not installed"; exit 1; }
  echo "ok: the OpenVDB plugin is installed"
fi

# 1. CMake package.
cmake -S "$here" -B "$work/cmake-build" -G Ninja -DCMAKE_PREFIX_PATH="$prefix" -DCMAKE_BUILD_TYPE=Release >/dev/null
cmake --build "$work/cmake-build" >/dev/null
libdir=$(dirname "${lib:-$prefix/lib/x}")
LD_LIBRARY_PATH="$libdir" "$work/cmake-build/consumer" "$work" 2>&1 | tee "$work/out.txt"
if grep -qi "validation error" "$work/out.txt"; then echo "FAIL: Vulkan validation errors"; exit 1; fi

# 2. pkg-config.
pcdir=$(dirname "$(ls "$prefix"/lib/*/pkgconfig/gsd.pc "$prefix"/lib/pkgconfig/gsd.pc 2>/dev/null | head -1)")
static=""
[ -z "$lib" ] && static=--static   # a static libgsd (GSD_SHARED=OFF) brings its dependencies
flags=$(PKG_CONFIG_PATH="$pcdir" pkg-config $static --cflags --libs gsd)
g++ -std=c++20 -O1 -I"$here/../../examples/vulkan_interop" "$here/main.cpp" "$here/../../examples/vulkan_interop/interop.cpp" -o "$work/consumer-pc" $flags -lvulkan
LD_LIBRARY_PATH="$libdir" "$work/consumer-pc" "$work" >/dev/null
echo "ok: pkg-config build ran"

# 3. The worked example of the interop API, as its README tells a user to build it.
cmake -S "$here/../../examples/vulkan_interop" -B "$work/example-build" -G Ninja -DCMAKE_PREFIX_PATH="$prefix" \
  -DCMAKE_BUILD_TYPE=Release >/dev/null
cmake --build "$work/example-build" >/dev/null
LD_LIBRARY_PATH="$libdir" "$work/example-build/vulkan_interop" "$here/../../data/demo/torus-holey.ply" \
  "$work/interop.png" | grep -E "adopted device vs|rendered on"
test -s "$work/interop.png"
echo "ok: examples/vulkan_interop built and ran"

# 4. The Python module, when it was built (GSD_PYTHON=ON): importable from the prefix alone.
if [ -d "$prefix"/lib/python3/dist-packages/gsd ]; then
  (cd "$work" && PYTHONPATH="$prefix"/lib/python3/dist-packages /usr/bin/python3 -c \
    "import gsd, numpy as np; w = gsd.winding_numbers(np.zeros((1, 3)), vertices=np.array([[1.,0,0],[0,1,0],[0,0,1],[-1,-1,-1.]]), faces=np.array([[0,1,2],[0,3,1],[1,3,2],[2,3,0]]), exact=True, device='cpu'); assert abs(abs(w[0]) - 1) < 1e-9, w; print('ok: import gsd from the prefix, gsd', gsd.version())")
fi
