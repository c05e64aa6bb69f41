#!/usr/bin/env bash
# Builds the libFuzzer targets (fuzz/, ASan + UBSan, library instrumented too) into build-san/
# (scripts/sanitizer-build.sh) and runs each for SECONDS (default 60), or, with FUZZ_RUNS=N set,
# for exactly N inputs from a fixed seed (a reproducible run: what CI does). Seeds: the
# checked-in fuzz/corpus/<target>/ plus fresh ones made by the project's own CLI (build-san/seeds/). New inputs collect in the writable
# build-san/corpus/<target>/, crashes in build-san/artifacts/<target>/, logs in
# build-san/logs/. Exits 1 if any target found a crash, leak, timeout or out-of-memory.
#
#   scripts/fuzz.sh [SECONDS]        FUZZ_TARGETS="mesh npy" scripts/fuzz.sh 30   (a subset)
#
# Reproduce a finding: build-san/bin/fuzz_<target> <crash file>. docs/io.md ("Fuzzing").
#
# The target `cli` (not in the default list: scripts/sanitize.sh runs CI's own campaign) is the
# CLI mutation campaign (tools/fuzz/mutate_cli.py through scripts/cli-campaign.sh): the regression
# inputs, then rounds of mutants of every format for SECONDS (or FUZZ_RUNS mutants per format),
# seed FUZZ_CLI_SEED (default 1; CI uses 1: pick another to try mutants CI never ran), extra
# mutate_cli.py options in FUZZ_CLI_ARGS; log in build-san/logs/cli.log, findings (with their
# reproducers) copied to build-san/cli-findings/.
#
#   FUZZ_TARGETS=cli FUZZ_CLI_SEED=9001 scripts/fuzz.sh 900     15 minutes, held-out seed
set -euo pipefail
script=$(realpath "$0")
cd "$(dirname "$script")/.."
root=$PWD
seconds=${1:-60}
[[ $seconds =~ ^[0-9]+$ ]] || { echo "usage: scripts/fuzz.sh [SECONDS]" >&2; exit 2; }
all_targets=(point_cloud mesh npy tori safetensors curve grid_metadata)
read -r -a targets <<< "${FUZZ_TARGETS:-${all_targets[*]}}"
for t in "${targets[@]}"; do
  [[ " ${all_targets[*]} cli " == *" $t "* ]] || { echo "fuzz: unknown target $t (${all_targets[*]} cli)" >&2; exit 2; }
done
build=build-san

# ---- build: the library, the CLI (for seeds) and the targets, all instrumented ---------------
# One sanitizer build serves the fuzzers and the sanitizer test suite (scripts/sanitize.sh).
fuzz_bins=()
for t in "${targets[@]}"; do
  if [ "$t" != cli ]; then fuzz_bins+=("fuzz_$t"); fi
done
bash scripts/sanitizer-build.sh gsd_cli "${fuzz_bins[@]}"

# Sanitizer settings for everything below. Leak checking stays on: the readers never touch
# Vulkan (the build has none), so a leak is a real one. One OpenMP thread: reproducible runs.
export ASAN_OPTIONS="detect_leaks=1:abort_on_error=1:symbolize=1:allocator_may_return_null=0"
export UBSAN_OPTIONS="print_stacktrace=1:halt_on_error=1"
export OMP_NUM_THREADS=1

# ---- seeds made by the project's own tools ---------------------------------------------------
# Multi-format targets take the extension from the first byte (fuzz/<target>.cpp), so their
# seeds get that byte in front: point_cloud 0 .ply 1 .xyz 2 .pc 3 .obj 4 .npy; mesh 0 .obj
# 1 .off 2 .stl 3 .ply; curve 0 .txt 1 .obj.
seeds=$build/seeds
make_seeds() {
  local gsd=$root/$build/bin/gsd tmp=$build/seeds.tmp
  rm -rf "$tmp" && mkdir -p "$tmp"/{work,point_cloud,mesh,npy,tori,safetensors,curve,grid_metadata}
  local w=$tmp/work
  seed() { local sel=$1 file=$2 out=$3; { printf "\\x$(printf %02x "$sel")"; cat "$file"; } > "$out"; }

  # Point clouds: every format gsd writes, from small noisy, holey samples.
  local i=0
  for ext in ply xyz pc obj npy; do
    $gsd -q sample torus -n 48 --noise 0.002 --holes 1 --flip 0.1 --seed 3 -o "$w/cloud.$ext"
    $gsd -q sample sphere -n 12 --seed 5 -o "$w/small.$ext"
    seed $i "$w/cloud.$ext" "$tmp/point_cloud/torus-48.$ext"
    seed $i "$w/small.$ext" "$tmp/point_cloud/sphere-12.$ext"
    i=$((i + 1))
  done
  # gsd writes binary PLY only: an ascii one by hand (colors, a face element after vertex).
  printf 'ply\nformat ascii 1.0\ncomment by scripts/fuzz.sh\nelement vertex 4\nproperty float x\nproperty float y\nproperty float z\nproperty float nx\nproperty float ny\nproperty float nz\nproperty uchar red\nproperty uchar green\nproperty uchar blue\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n0 0 0 0 0 1 255 0 0\n1 0 0 0 0 1 0 255 0\n0 1 0 0 0 1 0 0 255\n0 0 1 1 1 1 9 9 9\n3 0 1 2\n' > "$w/ascii.ply"
  seed 0 "$w/ascii.ply" "$tmp/point_cloud/ascii.ply"
  printf '# x y z nx ny nz\n0,0,0, 0,0,1\n1 0 0 0 0 1 # trailing comment\r\n\n+0 1 0 0 0 1\n' > "$w/hand.xyz"
  seed 1 "$w/hand.xyz" "$tmp/point_cloud/hand.xyz"

  # Meshes: every format gsd writes, a damaged sphere and a tiny box.
  i=0
  for ext in obj off stl ply; do
    $gsd -q mesh sphere -r 8 --holes 1 --flip 0.2 --seed 2 -o "$w/mesh.$ext"
    $gsd -q mesh rounded-box -r 8 -o "$w/box.$ext"
    seed $i "$w/mesh.$ext" "$tmp/mesh/sphere-r8.$ext"
    seed $i "$w/box.$ext" "$tmp/mesh/box-r8.$ext"
    i=$((i + 1))
  done
  # Forms gsd does not write: OBJ quads with v/t/n corners and negative indices, ascii STL,
  # ascii PLY with a uint index list, COFF with colors.
  printf 'mtllib x.mtl\no quad\nv 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nvt 0 0\nvn 0 0 1\ng a\ns off\nusemtl m\nf 1/1/1 2/1/1 3/1/1 4/1/1\nf -4//1 -2//1 -1//1\nl 1 2\n' > "$w/quad.obj"
  seed 0 "$w/quad.obj" "$tmp/mesh/quad.obj"
  # The same small mesh in every format gsd writes, through `gsd mesh --from` (faces flipped).
  printf 'v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nv 1 1 1\nf 1 3 2\nf 1 2 4\nf 1 4 3\nf 2 3 5 4\n' > "$w/tiny.obj"
  i=0
  for ext in obj off stl ply; do
    $gsd -q mesh --from "$w/tiny.obj" --flip 0.5 --seed 3 -o "$w/tiny-out.$ext"
    seed $i "$w/tiny-out.$ext" "$tmp/mesh/tiny.$ext"
    i=$((i + 1))
  done
  printf 'COFF\n# comment\n4 2 0\n0 0 0 255 0 0 255\n1 0 0 0 255 0 255\n1 1 0 0 0 255 255\n0 1 0 9 9 9 255\n3 0 1 2 1 0 0\n3 0 2 3\n' > "$w/colors.off"
  seed 1 "$w/colors.off" "$tmp/mesh/colors.off"
  printf 'solid t\n facet normal 0 0 1\n  outer loop\n   vertex 0 0 0\n   vertex 1 0 0\n   vertex 0 1 0\n  endloop\n endfacet\n facet normal 0 0 1\n  outer loop\n   vertex 1 0 0\n   vertex 1 1 0\n   vertex 0 1 0\n  endloop\n endfacet\nendsolid t\n' > "$w/ascii.stl"
  seed 2 "$w/ascii.stl" "$tmp/mesh/ascii.stl"
  printf 'ply\nformat ascii 1.0\nelement vertex 4\nproperty double x\nproperty double y\nproperty double z\nelement face 2\nproperty list uint uint vertex_index\nend_header\n0 0 0\n1 0 0\n1 1 0\n0 1\n0\n3 0 1 2\n3 0 2 3\n' > "$w/ascii.ply"
  seed 3 "$w/ascii.ply" "$tmp/mesh/ascii.ply"

  # Tori: both fitters, on a small cloud (TorusNet needs at least k points).
  $gsd -q sample torus -n 48 --seed 4 -o "$w/fit.ply"
  $gsd -q pat fit "$w/fit.ply" --fitter jet --k 8 -o "$tmp/tori/jet-48.tori"
  $gsd -q pat fit "$w/fit.ply" --fitter net --device cpu -o "$tmp/tori/net-48.tori"

  # .npy: numpy forms gsd does not write, by hand (python3 only, no numpy): float64 and
  # big-endian (M,3) query lists, a version 2.0 float64 grid, an int64 scalar ...
  python3 - "$tmp/npy" <<'PY'
import struct, sys
def npy(path, descr, shape, values, fmt, version=1):
    head = "{'descr': '%s', 'fortran_order': False, 'shape': %s, }" % (descr, shape)
    pre = 10 if version == 1 else 12
    head += " " * ((-(pre + len(head) + 1)) % 64) + "\n"
    size = struct.pack("<H", len(head)) if version == 1 else struct.pack("<I", len(head))
    with open(path, "wb") as f:
        f.write(b"\x93NUMPY" + bytes([version, 0]) + size + head.encode() + struct.pack(fmt, *values))
d = sys.argv[1]
q = [0.1, 0.2, 0.3, -1.0, 0.0, 1.0]
npy(d + "/queries-f8.npy", "<f8", "(2, 3)", q, "<6d")
npy(d + "/queries-be-f4.npy", ">f4", "(2, 3)", q, ">6f")
npy(d + "/grid-v2-f8.npy", "<f8", "(2, 2, 2)", range(8), "<8d", version=2)
npy(d + "/scalar-i8.npy", "<i8", "()", [7], "<q")
PY
  # ... and what gsd writes: an (N,6) cloud; a 3³ grid and its (3,3,3,3) gradient; φ (M,) and its
  # (M,3) gradient at those queries (`gsd pat eval`); int32 labels, one per face (`gsd swn`).
  $gsd -q sample sphere -n 16 -o "$tmp/npy/cloud-16x6.npy"
  $gsd -q pat eval --tori "$tmp/tori/jet-48.tori" --grid 3 --device cpu -o "$tmp/npy/grid-3.npy" \
    --gradient "$tmp/npy/grid-gradient-3.npy"
  mv "$tmp"/npy/*.npy.json "$tmp/grid_metadata/"  # the sidecars of those two grids
  $gsd -q pat eval --tori "$tmp/tori/jet-48.tori" --queries "$tmp/npy/queries-f8.npy" --device cpu \
    -o "$tmp/npy/phi-2.npy" --gradient "$tmp/npy/gradient-2x3.npy"
  $gsd -q mesh torus -r 8 -o "$w/torus8.obj"
  $gsd -q curve "$w/torus8.obj" --plane 0 1 0 0 --near 0.5 0 0 -o "$w/loop8.txt"
  $gsd -q swn "$w/torus8.obj" --curves "$w/loop8.txt" -o "$tmp/npy/labels-int32.npy"

  # TorusNet weights: the shipped model, and a tiny valid one (k 2, width 2, one block) by hand.
  cp models/torusnet.safetensors "$tmp/safetensors/shipped.safetensors"
  python3 - "$tmp/safetensors/tiny.safetensors" <<'PY'
import json, struct, sys
W, F, blocks = 2, 2, 1
shapes = {"embed.weight": [W, 7], "embed.bias": [W], "embed_norm.weight": [W], "embed_norm.bias": [W]}
for b in range(blocks):
    p = "blocks.%d." % b
    for name, s in [("norm1.weight", [W]), ("norm1.bias", [W]), ("qkv.weight", [3 * W, W]), ("qkv.bias", [3 * W]),
                    ("proj.weight", [W, W]), ("proj.bias", [W]), ("norm2.weight", [W]), ("norm2.bias", [W]),
                    ("fc1.weight", [F, W]), ("fc1.bias", [F]), ("fc2.weight", [W, F]), ("fc2.bias", [W])]:
        shapes[p + name] = s
shapes.update({"final_norm.weight": [W], "final_norm.bias": [W], "head.weight": [6, W], "head.bias": [6]})
header, data = {"__metadata__": {"format": "gsd-torusnet", "version": "1", "k": "2", "width": str(W),
                                 "blocks": str(blocks), "heads": "1", "mlp": str(F), "description": "fuzz seed"}}, b""
for name, s in shapes.items():
    n = 1
    for d in s: n *= d
    vals = struct.pack("<%df" % n, *[0.25 * ((i % 5) - 2) for i in range(n)])
    header[name] = {"dtype": "F32", "shape": s, "data_offsets": [len(data), len(data) + len(vals)]}
    data += vals
h = json.dumps(header).encode()
h += b" " * ((-len(h)) % 8)
open(sys.argv[1], "wb").write(struct.pack("<Q", len(h)) + h + data)
PY

  # Curves on `gsd mesh torus -r 16` (the mesh fuzz/curve.cpp reads them against), text and .obj.
  $gsd -q mesh torus -r 16 -o "$w/torus16.obj"
  $gsd -q curve "$w/torus16.obj" --plane 0 1 0 0 --near 0.5 0 0 -o "$w/loop.txt"
  $gsd -q curve "$w/torus16.obj" --sphere 0.39 0.31 0.2 0.28 --break 0.4 --seed 4 -o "$w/cut.txt"
  $gsd -q curve "$w/torus16.obj" --plane 0 0 1 0.05 --reverse 2 -o "$w/plane.txt"
  seed 0 "$w/cut.txt" "$tmp/curve/sphere-broken.txt"
  seed 0 "$w/plane.txt" "$tmp/curve/plane-reversed.txt"
  seed 0 "$w/loop.txt" "$tmp/curve/handle-loop.txt"
  printf '# 1-based, every record kind\nv 1\ne 2 0.5\nf 3 0.25 0.25\nn\nl 1 2 3\n#offset 0\nv 0\nl 3 0\n' > "$w/kinds.txt"
  seed 0 "$w/kinds.txt" "$tmp/curve/kinds.txt"
  printf 'v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nf 1 2 3\nl 1 2 3 4 1\nl -1 -2/1\np 3\n' > "$w/lines.obj"
  seed 1 "$w/lines.obj" "$tmp/curve/lines.obj"

  rm -rf "$w" "$seeds" && mv "$tmp" "$seeds"
}
if [ ! -d $seeds ] || [ $build/bin/gsd -nt $seeds ] || [ "$script" -nt $seeds ]; then
  echo "fuzz: making seeds with $build/bin/gsd"
  make_seeds
fi

# ---- run -------------------------------------------------------------------------------------
budget=(-max_total_time="$seconds") what="$seconds s"
[ -n "${FUZZ_RUNS:-}" ] && budget=(-runs="$FUZZ_RUNS" -seed=1) what="$FUZZ_RUNS inputs"
failed=()
summary=()
mkdir -p $build/logs
for t in "${targets[@]}"; do
  if [ "$t" = cli ]; then
    read -r -a cli_args <<< "${FUZZ_CLI_ARGS:-}"
    cli_args=(--seed "${FUZZ_CLI_SEED:-1}" "${cli_args[@]}")
    if [ -n "${FUZZ_RUNS:-}" ]; then cli_args=(--count "$FUZZ_RUNS" "${cli_args[@]}")
    else cli_args=(--minutes "$(awk "BEGIN { print $seconds / 60 }")" "${cli_args[@]}"); fi
    echo "fuzz: cli for $what (scripts/cli-campaign.sh ${cli_args[*]})"
    rc=0
    bash scripts/cli-campaign.sh "${cli_args[@]}" > $build/logs/cli.log 2>&1 || rc=$?
    total=$(grep -m1 '^TOTAL' $build/logs/cli.log | sed 's/^TOTAL *//' || true)
    line=$(printf '%-12s %s' cli "${total:-no summary}")
    if [ $rc -ne 0 ]; then
      failed+=(cli)
      line+="  FAILED (exit $rc; log $build/logs/cli.log)"
      found=$(sed -n '/finding(s):$/,$p' $build/logs/cli.log | grep -E '^- |reproduce:' | head -20 || true)
      line+=$'\n'"${found:-$(tail -5 $build/logs/cli.log)}"
    fi
    summary+=("$line")
    echo "$line"
    continue
  fi
  corpus=$build/corpus/$t artifacts=$build/artifacts/$t
  mkdir -p "$corpus" "$artifacts"
  cp -n fuzz/corpus/"$t"/* "$corpus"/ 2>/dev/null || true
  dict=()
  [ -f fuzz/dict/$t.dict ] && dict=(-dict=fuzz/dict/$t.dict)
  marker=$build/logs/$t.start
  touch "$marker"
  echo "fuzz: $t for $what"
  rc=0
  $build/bin/fuzz_$t "$corpus" "$seeds/$t" "${dict[@]}" "${budget[@]}" -rss_limit_mb=2048 \
    -timeout=20 -print_final_stats=1 -artifact_prefix="$artifacts/" \
    > $build/logs/$t.log 2>&1 &
  pid=$!
  { wait $pid; } 2>/dev/null || rc=$?  # (no "Aborted" job notice: the summary says it)
  # What a crashed run leaves: its input folder (fuzz/fuzz_input.hpp) and libomp's registration.
  rm -rf "${TMPDIR:-/dev/shm}"/gsd-fuzz-$pid-* /dev/shm/gsd-fuzz-$pid-* /tmp/gsd-fuzz-$pid-* \
    /dev/shm/__KMP_REGISTERED_LIB_${pid}_*
  execs=$(sed -n 's/^stat::number_of_executed_units: *//p' $build/logs/$t.log | tail -1)
  new_files=$(find "$artifacts" -type f -newer "$marker")
  line=$(printf '%-12s %10s executions, corpus %5d files' "$t" "${execs:-?}" "$(find "$corpus" -type f | wc -l)")
  if [ $rc -ne 0 ] || [ -n "$new_files" ]; then
    failed+=("$t")
    line+="  FAILED (exit $rc; log $build/logs/$t.log)"
    for f in $new_files; do line+=$'\n'"      input: $f"; done
    line+=$'\n'"      $(grep -m1 -E 'ERROR: (AddressSanitizer|LeakSanitizer|libFuzzer)|runtime error|ALARM|out-of-memory|deadly signal|uncaught exception|terminate called' $build/logs/$t.log || true)"
  fi
  summary+=("$line")
  echo "$line"
done

echo
echo "fuzz: summary ($what per target)"
printf '  %s\n' "${summary[@]}"
if [ ${#failed[@]} -gt 0 ]; then
  echo "fuzz: findings in: ${failed[*]} (inputs under $build/artifacts/<target>/; reproduce with $build/bin/fuzz_<target> FILE;" \
       "cli: the reproduce lines in $build/logs/cli.log, inputs under $build/cli-findings/)"
  exit 1
fi
echo "fuzz: no findings"
