#!/usr/bin/env bash
# Packs gsd-gpu-bench (or any gsd binaries) with the shared libraries it needs into one folder
# that runs on a machine with a GPU driver but none of gsd's build dependencies (a CUDA image,
# a render node): docs/gpu.md, "Benchmarking on a machine without gsd's dependencies".
#
#   scripts/gpu-bundle.sh OUT_DIR [BINARY ...]      (default: build/bin/gsd-gpu-bench)
#   OUT_DIR/run gsd-gpu-bench --full                (on the other machine)
#   OUT_DIR/bench gsd-gpu-bench --full              (the same, a stage per process)
#
# What is copied: every library the binaries load except the C runtime (libc, libm, libstdc++,
# libgcc_s and the loader, which any Linux machine has, newer). The BLAS and LAPACK that Debian's
# alternatives pick (OpenBLAS, 36 MB) are replaced by the reference ones, same ABI (gsd's dense
# algebra runs through Eigen; CHOLMOD alone calls them). The Vulkan loader is not linked (gsd
# opens it at run time): the machine's own libvulkan.so.1 is used, or $GSD_VULKAN_LOADER.
set -euo pipefail
cd "$(dirname "$0")/.."
out=${1:?usage: scripts/gpu-bundle.sh OUT_DIR [BINARY ...]}
shift
binaries=("$@")
[ ${#binaries[@]} -eq 0 ] && binaries=(build/bin/gsd-gpu-bench)
mkdir -p "$out/bin" "$out/lib"
arch=/usr/lib/x86_64-linux-gnu
for b in "${binaries[@]}"; do
  [ -x "$b" ] || { echo "gpu-bundle: $b is not an executable (build it first)" >&2; exit 1; }
  cp "$b" "$out/bin/"
  ldd "$b" | awk '/=>/ {print $1, $3}' | while read -r name path; do
    case "$name" in
      libc.so.*|libm.so.*|libstdc++.so.*|libgcc_s.so.*|libpthread.so.*|libdl.so.*|librt.so.*|ld-linux*|libopenblas.so.*) continue ;;
      libblas.so.3) [ -f "$arch/blas/libblas.so.3" ] && path=$arch/blas/libblas.so.3 ;;
      liblapack.so.3) [ -f "$arch/lapack/liblapack.so.3" ] && path=$arch/lapack/liblapack.so.3 ;;
    esac
    cp -L "$path" "$out/lib/$name"
  done
done
cat > "$out/run" <<'EOF'
#!/usr/bin/env bash
# Runs a bundled binary with the bundle's libraries: run NAME [ARGS...]
here=$(cd "$(dirname "$0")" && pwd)
name=$1
shift
LD_LIBRARY_PATH="$here/lib${LD_LIBRARY_PATH:+:$LD_LIBRARY_PATH}" exec "$here/bin/$name" "$@"
EOF
cat > "$out/bench" <<'EOF'
#!/usr/bin/env bash
# The GPU table, a stage per process (each with its own time limit, so one slow stage cannot
# take the others with it): bench [BINARY [gsd-gpu-bench arguments...]]
here=$(cd "$(dirname "$0")" && pwd)
bin=${1:-gsd-gpu-bench}
shift || true
first=1
for stage in pat winding render shm net; do
  out=$(timeout "${GSD_STAGE_TIMEOUT:-150}" "$here/run" "$bin" --stages "$stage" "$@" 2>&1)
  status=$?
  if [ $first = 1 ]; then echo "$out" | grep -v '^note:'; first=0; else echo "$out" | grep -v '^note:' | tail -n +3; fi
  [ $status = 124 ] && echo "$stage: stopped after ${GSD_STAGE_TIMEOUT:-150} s"
done
exit 0
EOF
chmod +x "$out/run" "$out/bench"
echo "gpu-bundle: $(du -sh "$out" | cut -f1) in $out ($(ls "$out/lib" | wc -l) libraries)"
