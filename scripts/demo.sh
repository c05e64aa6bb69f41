#!/usr/bin/env bash
# The main job on gsd's own sample data: a holey, noisy sampling of a procedural torus
# (data/demo/torus-holey.ply, made by `gsd sample`) → fitted tori → signed distance grid
# and gradient → zero-level mesh → slice pictures, with the SSPD baseline beside it.
# Usage: scripts/demo.sh [OUTPUT_DIR]   (default: out/demo)
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup-deps.sh
bash scripts/build.sh >/dev/null
gsd=build/bin/gsd
out=${1:-out/demo}
mkdir -p "$out"
export XDG_RUNTIME_DIR=${XDG_RUNTIME_DIR:-/tmp}

cloud=data/demo/torus-holey.ply
if [ ! -f "$cloud" ]; then  # the committed sample, regenerated if missing
  mkdir -p data/demo
  "$gsd" sample torus -n 4096 --noise 0.002 --normal-noise 0.05 --holes 3 --hole-radius 0.08 --seed 7 -o "$cloud"
fi
bounds="-1 -1 -1 1 1 1"

"$gsd" info
"$gsd" -v pat fit "$cloud" -o "$out/torus.tori"
"$gsd" -v pat eval --tori "$out/torus.tori" --grid 96 --bounds $bounds -o "$out/sdf.npy" --gradient "$out/sdf-gradient.npy"
"$gsd" contour "$out/sdf.npy" --bounds $bounds -o "$out/surface.obj"
"$gsd" slice "$out/sdf.npy" --bounds $bounds --axis z --at 0 -o "$out/slice-z.png"
"$gsd" slice "$out/sdf.npy" --bounds $bounds --axis y --at 0 -o "$out/slice-y.png"
"$gsd" -v baseline sspd "$cloud" --grid 96 --bounds $bounds -o "$out/sspd.npy"
"$gsd" slice "$out/sspd.npy" --bounds $bounds --axis y --at 0 -o "$out/sspd-slice-y.png"

cat <<MSG

demo outputs (input: $cloud, $(head -c 300 "$cloud" | grep -a 'element vertex' | cut -d' ' -f3) points):
  fitted tori          $out/torus.tori
  SDF grid 96^3        $out/sdf.npy           (float32, C order, bounds $bounds)
  SDF gradient         $out/sdf-gradient.npy  (96,96,96,3)
  zero-level mesh      $out/surface.obj
  slices               $out/slice-z.png  $out/slice-y.png
  SSPD baseline        $out/sspd.npy  $out/sspd-slice-y.png
MSG
