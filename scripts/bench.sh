#!/usr/bin/env bash
# Benchmarks, printed as tables. Every comparison is measured side by side in this one run.
#   scripts/bench.sh            everything
#   scripts/bench.sh pat        PAT fit/evaluation throughput (CPU vs GPU) and the accuracy table
#   scripts/bench.sh shm        SHM time and peak memory vs resolution and vs source size,
#                               step 1 / step 3, CPU vs GPU, multigrid vs CG vs direct
#   scripts/bench.sh adaptive   the adaptive SHM: nodes, wall time and peak memory vs depth, beside the
#                               uniform grid of the same finest spacing (as far as it fits), and step 1
#                               on the device vs the CPU (GSD_BENCH_ADAPTIVE_MAX: deepest level, default 9;
#                               GSD_BENCH_ADAPTIVE_POINTS: the torus cloud's size, default 150000)
#   scripts/bench.sh net        TorusNet fit throughput (points/s), CPU reference vs GPU kernels
#   scripts/bench.sh surface    SHM on surfaces: accuracy vs exact distances (and vs a reference
#                               program when one is there), setup/solve times and memory vs mesh
#                               size, first vs repeated solves, whole runs side by side
#   scripts/bench.sh sums       the fast summation engine: winding numbers (whole runs of 10⁶
#                               queries against the exact sum and libigl's fast_winding_number;
#                               treecode vs exact sum on grids: time, terms per query; CPU and GPU)
#                               and SHM step 1 on broken meshes with coarse faces (step 1 / step 3
#                               seconds, terms)
#   scripts/bench.sh gpu        one table of every query-heavy stage, CPU path vs device (gsd-gpu-bench:
#                               PAT evaluation, winding numbers, the sdf distance, a PAT render, SHM step 1 / step 3,
#                               TorusNet fit; full sizes on a hardware GPU, small ones on lavapipe;
#                               GSD_BENCH_GPU_ARGS adds arguments, e.g. --full or --stages pat,winding)
#   scripts/bench.sh sdf        gsd sdf: its signs on broken closed meshes beside ray parity (gsd-sdf-bench),
#                               whole runs of 10⁶ queries and 5·10⁵ samples, Open3D's unsigned BVH if installed
#   scripts/bench.sh swn        Surface Winding Numbers: mislabeled area on a synthetic benchmark
#                               (SWN full and reduced, naive rounding, SHM sign, a reference program
#                               when one is there), time per step vs mesh size, whole runs
# Environment: GSD_BENCH_PAT_ARGS (extra gsd-bench arguments), GSD_BENCH_SHM_MAX (largest grid,
# default 256; 512 needs a big GPU), GSD_BENCH_NET_SIZES (TorusNet cloud sizes, default
# 10000,100000; 1000000 and up want a real GPU: lavapipe fits ~2·10³ points/s),
# GSD_BENCH_SURFACE_LEVELS (icosphere levels for the surface timing, default 4,5,6,7,8: 5k to
# 1.3M faces), GSD_SURFACE_REFERENCE (a program `REF MESH.obj CURVES.txt -o OUT.npy` to compare
# with, e.g. geometry-central's signed heat solver; default: ../shared/anchors/gc_shm if present),
# GSD_BENCH_SWN_CASES (random functions per mesh, default 3), GSD_BENCH_SWN_MESHES (§7.1 meshes, default
# 8), GSD_BENCH_SWN_SIZES (double-torus grid
# sizes for the SWN timing), GSD_SWN_REFERENCE (a program `REF MESH.obj CURVES.txt -o PREFIX` writing
# PREFIX.labels.npy, e.g. the SWN reference code; default: ../shared/anchors/swn_clp if present),
# GSD_IGL_WN (libigl's fast winding number as `REF mesh MESH.obj Q.npy OUT.npy --threads T`;
# default: ../shared/anchors/igl_wn if present).
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup-deps.sh
bash scripts/build.sh >/dev/null
export XDG_RUNTIME_DIR=${XDG_RUNTIME_DIR:-/tmp}
gsd=build/bin/gsd
what=${1:-all}
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT

echo "== machine: $(nproc) cores; $($gsd info | grep -- '--device gpu')"

if [ "$what" = all ] || [ "$what" = gpu ]; then
  echo
  echo "== GPU kernels against the CPU path (docs/gpu.md, \"Throughput\")"
  size=""
  "$gsd" info | grep -- '--device auto' | grep -qv 'CPU path' && size="--full"  # a hardware GPU
  # shellcheck disable=SC2086
  build/bin/gsd-gpu-bench $size ${GSD_BENCH_GPU_ARGS:-}
fi

if [ "$what" = all ] || [ "$what" = pat ]; then
  echo
  echo "== Points as Tori"
  # shellcheck disable=SC2086
  build/bin/gsd-bench ${GSD_BENCH_PAT_ARGS:-}
  echo
  build/bin/gsd-accuracy --grid 64
fi

# One SHM run through the CLI; prints a table row from its --verbose report.
shm_row() {  # label, input, grid, device, solver
  local log="$work/log"
  if ! "$gsd" -v shm grid "$2" --grid "$3" --bounds -1 -1 -1 1 1 1 --device "$4" --solver "$5" \
        -o "$work/out.npy" >"$log" 2>&1; then
    printf "%-10s %6s %-6s %-7s  failed: %s\n" "$1" "$3" "$4" "$5" "$(grep 'error' "$log" | head -1)"
    return
  fi
  local s1 s3 it res mem terms exact
  s1=$(sed -n 's/.*step 1 (diffuse): \([0-9.]*\) s.*/\1/p' "$log")
  exact=$(sed -n 's/.*s, \([0-9]*\) of [0-9]* nodes summed.*/\1/p' "$log")
  terms=$(sed -n 's/.*exactly, \([0-9]*\) kernel terms.*/\1/p' "$log")
  s3=$(sed -n 's/.*step 3 (solve): \([0-9.]*\) s.*/\1/p' "$log")
  it=$(sed -n 's/.*, \([0-9]*\) iterations.*/\1/p' "$log")
  res=$(sed -n 's/.*iterations, relative residual \([0-9.e+-]*\).*/\1/p' "$log")
  mem=$(sed -n 's/.*peak memory: \(.*\)/\1/p' "$log")
  printf "%-10s %6s %-6s %-7s %9s %9s %6s %9s %10s %12s %12s\n" "$1" "$3" "$4" "$5" "$s1" "$s3" "$it" "$res" "$mem" "$exact" "$terms"
}

if [ "$what" = all ] || [ "$what" = net ]; then
  echo
  echo "== TorusNet"
  build/bin/gsd-bench --net --sizes "${GSD_BENCH_NET_SIZES:-10000,100000}"
fi

if [ "$what" = all ] || [ "$what" = shm ]; then
  max=${GSD_BENCH_SHM_MAX:-256}
  echo
  echo "== Signed Heat Method: 100k-point torus cloud, box [-1,1]^3 (times in seconds)"
  "$gsd" -q sample torus -n 100000 -o "$work/t100k.ply"
  printf "%-10s %6s %-6s %-7s %9s %9s %6s %9s %10s %12s %12s\n" source grid device solver step1 step3 iters residual "peak mem" "exact nodes" "kernel terms"
  for n in 64 128 256 512; do
    [ "$n" -le "$max" ] || continue
    shm_row 100k "$work/t100k.ply" "$n" cpu mg
    shm_row 100k "$work/t100k.ply" "$n" gpu mg
    [ "$n" -le 128 ] && shm_row 100k "$work/t100k.ply" "$n" cpu cg
    [ "$n" -le 64 ] && shm_row 100k "$work/t100k.ply" "$n" cpu direct
  done
  echo
  echo "== SHM step 1 vs source size (128^3 grid, CPU): work per node stays bounded"
  printf "%-10s %6s %-6s %-7s %9s %9s %6s %9s %10s %12s %12s\n" source grid device solver step1 step3 iters residual "peak mem" "exact nodes" "kernel terms"
  for m in 10000 30000 100000 300000; do
    "$gsd" -q sample torus -n "$m" -o "$work/t$m.ply"
    shm_row "$m" "$work/t$m.ply" 128 cpu mg
  done
fi

# One whole run, timed; prints "seconds peak" from its --verbose report. Arguments: log, command...
timed_run() {
  local log=$1
  shift
  local t0 t1
  t0=$(date +%s.%N)
  if ! "$@" >"$log" 2>&1; then
    echo "failed: $(grep -m1 error "$log")"
    return
  fi
  t1=$(date +%s.%N)
  printf "%.2f %s\n" "$(awk "BEGIN{print $t1 - $t0}")" "$(sed -n 's/.*peak \(memory: \)\{0,1\}\([0-9.]* [KMG]iB\).*/\2/p' "$log" | tail -1)"
}

if [ "$what" = all ] || [ "$what" = adaptive ]; then
  maxd=${GSD_BENCH_ADAPTIVE_MAX:-9}
  npts=${GSD_BENCH_ADAPTIVE_POINTS:-150000}
  echo
  echo "== Adaptive SHM (docs/shm-adaptive.md): a ${npts}-point torus cloud (noise 0.001, 3 holes), whole runs"
  "$gsd" -q sample torus -n "$npts" --noise 0.001 --holes 3 -o "$work/ta.ply"
  # The adaptive grid's cube, so that the uniform grid of 2^D + 1 nodes has the same spacing.
  cube=$("$gsd" shm adaptive "$work/ta.ply" --depth 2 --grid 2 -o "$work/a.npy" --device cpu 2>&1 |
         sed -n 's/.*octree cube: --bounds \(.*\)/\1/p')
  printf "%-6s %11s %-8s %9s %11s | %-9s %9s %11s | %7s %7s\n" depth nodes device seconds "peak" "uniform" seconds "peak" time mem
  for d in 7 8 9 10 11; do
    [ "$d" -le "$maxd" ] || continue
    read -r as am au < <(timed_run "$work/a.log" "$gsd" -v shm adaptive "$work/ta.ply" --depth "$d" --bounds $cube \
                           --grid 8 -o "$work/a.npy" --device cpu)
    nodes=$(sed -n 's/.*), \([0-9]*\) nodes; .*/\1/p' "$work/a.log")
    n=$(( (1 << d) + 1 ))
    us="—"; um=""; uu=""; rt="—"; rm="—"
    if [ "$d" -le 8 ]; then  # 513^3 wants ~13 GB
      read -r us um uu < <(timed_run "$work/u.log" "$gsd" -v shm grid "$work/ta.ply" --grid "$n" --bounds $cube \
                             -o "$work/u.npy" --device cpu)
      rt=$(awk "BEGIN{printf \"%.2f\", $as / $us}")
      rm=$(awk "BEGIN{printf \"%.2f\", $am / $um}")
    fi
    printf "%-6s %11s %-8s %9s %11s | %-9s %9s %11s | %7s %7s\n" "$d" "$nodes" cpu "$as" "$am $au" "${n}^3" "$us" "$um $uu" "$rt" "$rm"
    if [ "$d" -le 8 ]; then
      read -r gs gm gu < <(timed_run "$work/g.log" "$gsd" -v shm adaptive "$work/ta.ply" --depth "$d" --bounds $cube \
                             --grid 8 -o "$work/g.npy" --device gpu)
      s1c=$(sed -n 's/.*step 1 (diffuse): \([0-9.]*\) s.*/\1/p' "$work/a.log")
      s1g=$(sed -n 's/.*step 1 (diffuse): \([0-9.]*\) s.*/\1/p' "$work/g.log")
      dev=$(sed -n 's/.*step 1 on \(.*\)/\1/p' "$work/g.log")
      printf "%-6s %11s %-8s %9s %11s | step 1: device %s s, CPU %s s (%s)\n" "$d" "$nodes" gpu "$gs" "$gm $gu" "$s1g" "$s1c" "$dev"
    fi
  done
  echo "(time, mem: adaptive over uniform; the accuracy at equal nodes is in docs/shm-adaptive.md, tests/test_shm_adaptive.cpp)"
fi

if [ "$what" = all ] || [ "$what" = surface ]; then
  ref=${GSD_SURFACE_REFERENCE:-}
  [ -z "$ref" ] && [ -x ../shared/anchors/gc_shm ] && ref=$(cd ../shared/anchors && pwd)/gc_shm
  echo
  echo "== Signed Heat Method on surfaces: accuracy (exact geodesic distances)"
  if [ -n "$ref" ]; then
    build/bin/gsd-surface-bench accuracy --reference "$ref" --work "$work/acc"
  else
    build/bin/gsd-surface-bench accuracy --work "$work/acc"
  fi
  echo
  echo "== Signed Heat Method on surfaces: curves that bound nothing (L1 integration)"
  build/bin/gsd-surface-bench nonbounding
  echo
  echo "== Signed Heat Method on surfaces: time and memory vs mesh size"
  build/bin/gsd-surface-bench timing --levels "${GSD_BENCH_SURFACE_LEVELS:-4,5,6,7,8}"
  if [ -n "$ref" ]; then
    echo
    echo "== Whole runs side by side (load, factor, solve, write; median of 3, alternating)"
    printf "%-26s %9s %9s %9s %8s
" input faces gsd reference ratio
    build/bin/gsd-surface-bench write 6 "$work/ico6" >/dev/null
    runs=("$work/ico6.obj $work/ico6.txt")
    if [ -d ../shared/data/surface-curves ]; then
      d=../shared/data/surface-curves
      runs+=("$d/bunny.obj $d/bunny-brokenheart.txt" "$d/spots-on-spot.obj $d/spots-on-spot.txt" "$d/S.obj $d/S.txt")
    fi
    median() { sort -g | sed -n 2p; }
    for r in "${runs[@]}"; do
      set -- $r
      g=(); c=()
      for i in 1 2 3; do
        t0=$(date +%s.%N); "$gsd" -q shm surface "$1" --curves "$2" -o "$work/g.npy"; t1=$(date +%s.%N)
        "$ref" "$1" "$2" -o "$work/r.npy" -q >/dev/null 2>&1; t2=$(date +%s.%N)
        g+=("$(awk "BEGIN{print $t1 - $t0}")"); c+=("$(awk "BEGIN{print $t2 - $t1}")")
      done
      gm=$(printf "%s\n" "${g[@]}" | median); cm=$(printf "%s\n" "${c[@]}" | median)
      faces=$(grep -c '^f ' "$1")
      printf "%-26s %9s %9.3f %9.3f %8.2f\n" "$(basename "$1" .obj)/$(basename "$2")" "$faces" "$gm" "$cm" "$(awk "BEGIN{print $gm / $cm}")"
    done
  fi
fi

if [ "$what" = all ] || [ "$what" = sums ]; then
  echo "## Fast winding numbers against the exact sum and libigl (CPU, 2 threads; GPU if there is one)"
  igl=${GSD_IGL_WN:-}
  [ -z "$igl" ] && [ -x ../shared/anchors/igl_wn ] && igl=../shared/anchors/igl_wn
  gpu_flag=""  # a hardware device only: lavapipe would take minutes for 10⁶ queries
  "$gsd" info | grep -- '--device auto' | grep -qv 'CPU path' && gpu_flag="--gpu"
  build/bin/gsd-winding-bench --work "$work/wn" ${igl:+--igl "$igl"} $gpu_flag
  echo
  echo "## Fast winding numbers on grids: broken double torus (10% of the area in 3 holes, 5% flipped)"
  "$gsd" -q mesh double-torus -r 110 -o "$work/dt.obj"
  "$gsd" -q mesh --from "$work/dt.obj" --holes 3 --hole-area 0.1 --flip 0.05 -o "$work/dtb.obj"
  printf "%-28s %10s %14s %12s\n" "run" "seconds" "queries/s" "terms/query"
  wn_row() {  # label, grid, extra args
    local t0 t1 line
    t0=$(date +%s.%N)
    line=$("$gsd" -v winding "$work/dtb.obj" --grid "$2" -o "$work/w_$1.npy" $3 2>&1 | grep "terms per query" | sed 's/.*, \([0-9.e+]*\) terms per query/\1/')
    t1=$(date +%s.%N)
    awk -v l="$1" -v a="$t0" -v b="$t1" -v n="$2" -v t="$line" 'BEGIN { printf "%-28s %10.2f %14.3g %12s\n", l, b - a, n^3 / (b - a), t }'
  }
  wn_row "fast cpu (default) 100^3" 100 "--device cpu"
  wn_row "fast cpu (beta 2 alone) 100^3" 100 "--device cpu --beta 2 --tolerance 0"
  wn_row "fast gpu (default) 100^3" 100 "--device gpu"
  wn_row "exact cpu 24^3" 24 "--device cpu --exact"
  wn_row "fast cpu (default) 24^3" 24 "--device cpu"
  echo "(max |fast − exact| on the 24^3 grid: compare $work/w_fast*24*.npy with the exact run; docs/sums.md)"
  echo
  echo "## Inside/outside on broken meshes (holes, flips, duplicates, self-crossing), 64^3"
  real=""
  for m in bunny_small pat-block pat-femur rocker polygon-bear; do
    [ -f "../shared/data/meshes/$m.obj" ] && real="$real ../shared/data/meshes/$m.obj"
  done
  build/bin/gsd-broken-bench $real
  echo "(the same with the mean shift alone, no zero-set fit: --fit-zero-set 0)"
  build/bin/gsd-broken-bench --fit-zero-set 0 $real
  echo
  echo "## SHM step 1 on broken meshes with coarse faces (whole runs, default bounds)"
  "$gsd" -q mesh capsule -r 16 -o "$work/cap.obj"
  "$gsd" -q mesh --from "$work/cap.obj" --holes 3 --hole-area 0.15 --flip 0.05 -o "$work/capb.obj"
  inputs="$work/capb.obj"
  [ -f ../shared/data/meshes/chair.obj ] && inputs="$inputs ../shared/data/meshes/chair.obj"
  printf "%-12s %5s %6s %10s %10s %14s\n" "mesh" "grid" "device" "step 1 s" "step 3 s" "kernel terms"
  for m in $inputs; do
    for n in 64 96; do
      for dev in cpu gpu; do
        out=$("$gsd" -v shm grid "$m" --grid "$n" -o "$work/s.npy" --device "$dev" 2>&1)
        s1=$(echo "$out" | sed -n 's/.*step 1 (diffuse): \([0-9.]*\) s, .*/\1/p')
        s3=$(echo "$out" | sed -n 's/.*step 3 (solve): \([0-9.]*\) s.*/\1/p')
        terms=$(echo "$out" | sed -n 's/.*exactly, \([0-9]*\) kernel terms/\1/p')
        printf "%-12s %5s %6s %10s %10s %14s\n" "$(basename "$m" .obj)" "$n" "$dev" "$s1" "$s3" "$terms"
      done
    done
  done
  echo
fi

if [ "$what" = all ] || [ "$what" = swn ]; then
  ref=${GSD_SWN_REFERENCE:-}
  [ -z "$ref" ] && [ -x ../shared/anchors/swn_clp ] && ref=$(cd ../shared/anchors && pwd)/swn_clp
  echo
  echo "== Surface Winding Numbers: mislabeled area on a synthetic benchmark (thesis §6.3 style)"
  # shellcheck disable=SC2086
  build/bin/gsd-swn-bench accuracy --cases "${GSD_BENCH_SWN_CASES:-3}" ${ref:+--reference "$ref"} --work "$work/swn"
  echo
  echo "== Surface Winding Numbers: a broken small loop beside a broken loop around the tube (3 gaps, one piece reversed)"
  # shellcheck disable=SC2086
  build/bin/gsd-swn-bench broken-loops --seeds 8 ${ref:+--reference "$ref"} --work "$work/swn"
  echo
  echo "== Surface Winding Numbers: the same with the loop around the hole, half of each loop cut away"
  # shellcheck disable=SC2086
  build/bin/gsd-swn-bench broken-loops --seeds 8 --cut 0.5 --around hole ${ref:+--reference "$ref"} --work "$work/swn"
  echo
  echo "== Inside/outside, thesis §7.1: level sets of Laplacian eigenfunctions with offsets, half deleted (SWN, SHM's sign, reference)"
  # shellcheck disable=SC2086
  build/bin/gsd-swn-bench section71 --meshes "${GSD_BENCH_SWN_MESHES:-8}" ${ref:+--reference "$ref"} --work "$work/swn"
  echo
  echo "== Surface Winding Numbers: time per step, full vs reduced program, vs mesh size"
  build/bin/gsd-swn-bench timing --sizes "${GSD_BENCH_SWN_SIZES:-32,48,64,96,128}"
  if [ -d ../shared/data/surface-curves ]; then
    d=../shared/data/surface-curves
    echo
    echo "== Whole runs on the shared double tori (seconds; the reference's full program only with GSD_BENCH_SWN_SLOW=1)"
    printf "%-34s %9s %9s %12s %12s\n" input "gsd full" "gsd red." "ref approx" "ref full"
    for m in DoubleTorusWithLoops DoubleTorusWithBrokenLoops; do
      t0=$(date +%s.%N); "$gsd" -q swn "$d/$m.obj" --lp full -o "$work/f.npy"; t1=$(date +%s.%N)
      "$gsd" -q swn "$d/$m.obj" --lp reduced -o "$work/r.npy"; t2=$(date +%s.%N)
      ra=-; rf=-
      if [ -n "$ref" ]; then
        "$ref" "$d/$m.obj" -o "$work/ra" --approx >/dev/null 2>&1; t3=$(date +%s.%N)
        ra=$(awk "BEGIN{printf \"%.2f\", $t3 - $t2}")
        if [ "${GSD_BENCH_SWN_SLOW:-0}" = 1 ]; then
          "$ref" "$d/$m.obj" -o "$work/rf" >/dev/null 2>&1; t4=$(date +%s.%N)
          rf=$(awk "BEGIN{printf \"%.1f\", $t4 - $t3}")
        fi
      fi
      printf "%-34s %9.2f %9.2f %12s %12s\n" "$m" "$(awk "BEGIN{print $t1 - $t0}")" "$(awk "BEGIN{print $t2 - $t1}")" "$ra" "$rf"
    done
  fi
fi

if [ "$what" = all ] || [ "$what" = sdf ]; then
  echo
  echo "== Signed distance to broken meshes (docs/sdf.md): the signs on broken closed meshes, beside ray parity"
  build/bin/gsd-sdf-bench --queries "${GSD_BENCH_SDF_QUERIES:-20000}"
  echo
  echo "== gsd sdf whole runs: 10^6 uniform queries around a 9·10^4-face broken double torus"
  "$gsd" -q mesh double-torus -r 110 --holes 3 --hole-area 0.1 --flip 0.05 -o "$work/dt.obj"
  py=/usr/bin/python3  # Debian's, with NumPy (scripts/setup-deps.sh); not a virtual environment's
  [ -x "$py" ] || py=python3
  "$py" - "$work/q.npy" <<'PY'
import sys, numpy as np
np.save(sys.argv[1], np.random.default_rng(1).uniform(-1.3, 1.3, (1000000, 3)))
PY
  for sign in none auto; do
    /usr/bin/time -f "gsd sdf --sign $sign: %e s wall, %M KiB peak" "$gsd" -q sdf "$work/dt.obj" --queries "$work/q.npy" \
      --sign "$sign" --device cpu -o "$work/sdf.npy"
  done
  /usr/bin/time -f "gsd sdf --samples 500000: %e s wall, %M KiB peak" "$gsd" -q sdf "$work/dt.obj" --samples 500000 \
    --device cpu -o "$work/samples.npy"
  # Open3D's BVH, where Debian's python3-open3d is installed (its unsigned distance only: its ray
  # casting returns no hits there, so it cannot give a sign).
  if "$py" -c "import open3d" 2>/dev/null; then
    "$py" - "$work/dt.obj" "$work/q.npy" <<'PY'
import sys, time, numpy as np, open3d as o3d
m = o3d.io.read_triangle_mesh(sys.argv[1]); q = np.load(sys.argv[2]).astype(np.float32)
V = np.asarray(m.vertices, dtype=np.float32); F = np.asarray(m.triangles, dtype=np.uint32)
t0 = time.perf_counter()
scene = o3d.t.geometry.RaycastingScene(); scene.add_triangles(o3d.core.Tensor(V), o3d.core.Tensor(F))
scene.compute_distance(o3d.core.Tensor(q))
print("Open3D RaycastingScene build + compute_distance (unsigned): %.2f s" % (time.perf_counter() - t0))
PY
  fi
fi
