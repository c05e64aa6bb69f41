#!/usr/bin/env bash
# The main jobs on gsd's own sample data:
#  1. Points as Tori on a holey, noisy sampling of a procedural torus (data/demo/torus-holey.ply,
#     made by `gsd sample`) → fitted tori → SDF grid and gradient → zero-level mesh → slices and
#     a sphere-traced picture of the field, with the SSPD baseline beside it;
#  2. the Signed Heat Method on a broken mesh of a rounded box — 20% of its area cut away in
#     3 holes, 10% of its faces flipped (data/demo/box-broken.ply, made by `gsd mesh`) → SDF grid
#     → a closed zero-level surface → a slice, beside the fast generalized winding number (`gsd
#     winding`) and its ½ level;
#  3. the Signed Heat Method on a surface: a torus mesh (`gsd mesh`) and a closed curve on it with
#     40% cut away in three gaps (`gsd curve`) → geodesic signed distance per vertex → a picture,
#     isolines and a colored mesh; the same on a point cloud sampled from a torus (no mesh): a
#     broken curve through its points → φ per point → a picture of a disc per point;
#  4. Surface Winding Numbers on a double torus (`gsd mesh double-torus`): a loop around a region
#     and loops around both handles, each with 30% cut away (`gsd curve`) → inside/outside labels
#     per face, the loops that bound nothing found and completed → pictures, beside the labels
#     from the sign of the surface Signed Heat Method.
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
scan2=data/demo/capsule-holey.ply
if [ ! -f "$scan2" ]; then  # a second scan: a capsule through the torus's hole, holes of its own
  "$gsd" sample capsule -n 4096 --noise 0.002 --normal-noise 0.05 --holes 2 --hole-radius 0.08 --seed 11 -o "$scan2"
fi
broken=data/demo/box-broken.ply
if [ ! -f "$broken" ]; then
  "$gsd" mesh rounded-box -r 28 --holes 3 --hole-area 0.2 --flip 0.1 --seed 3 -o "$broken"
fi
bounds="-1 -1 -1 1 1 1"

"$gsd" info
"$gsd" -v pat fit "$cloud" -o "$out/torus.tori"
"$gsd" -v pat eval --tori "$out/torus.tori" --grid 96 --bounds $bounds -o "$out/sdf.npy" --gradient "$out/sdf-gradient.npy"
"$gsd" contour "$out/sdf.npy" --bounds $bounds -o "$out/surface.obj"
"$gsd" slice "$out/sdf.npy" --bounds $bounds --axis z --at 0 -o "$out/slice-z.png"
"$gsd" slice "$out/sdf.npy" --bounds $bounds --axis y --at 0 -o "$out/slice-y.png"
"$gsd" -v render --tori "$out/torus.tori" --size 640 480 -o "$out/render.png"   # sphere-traced, shaded by ∇φ
"$gsd" -v baseline sspd "$cloud" --grid 96 --bounds $bounds -o "$out/sspd.npy"
"$gsd" slice "$out/sspd.npy" --bounds $bounds --axis y --at 0 -o "$out/sspd-slice-y.png"

"$gsd" -v shm grid "$broken" --grid 96 --bounds $bounds -o "$out/shm.npy" --contour "$out/shm-surface.obj"
"$gsd" slice "$out/shm.npy" --bounds $bounds --axis z --at 0 -o "$out/shm-slice-z.png"
"$gsd" render "$out/shm.npy" --size 640 480 -o "$out/shm-render.png"
"$gsd" -v winding "$broken" --grid 96 --bounds $bounds -o "$out/winding.npy"   # the classic answer, for comparison
"$gsd" slice "$out/winding.npy" --bounds $bounds --axis z --at 0 --level 0.5 -o "$out/winding-slice-z.png"

# Fields made of fields: the torus of the holey cloud (PAT) joined smoothly to the broken box's
# SHM distance shrunk by 0.3, on a grid and in a picture (docs/field.md).
expr="smooth_union('$out/torus.tori', offset('$out/shm.npy', -0.3), 0.15)"
"$gsd" -v field "$expr" --grid 96 --bounds $bounds -o "$out/field.npy"
"$gsd" -v render --expr "$expr" --size 640 480 --view-from 1 1.4 1.2 -o "$out/field-render.png"
# Two scans: the torus minus the capsule (smoothly), and the sharp difference's opening by 0.08,
# which removes the slivers thinner than 0.16 that the two scans' disagreement leaves.
"$gsd" -v render --expr "smooth_difference('$out/torus.tori', '$scan2', 0.04)" --size 480 360 --view-from 1 1.4 1.2 \
  -o "$out/scans-difference.png"
"$gsd" -v render --expr "opening(difference('$out/torus.tori', '$scan2'), 0.08)" --size 480 360 --view-from 1 1.4 1.2 \
  -o "$out/scans-opening.png"

surf_mesh="$out/torus-mesh.ply"
"$gsd" mesh torus -r 72 -o "$surf_mesh"
"$gsd" curve "$surf_mesh" --sphere 0.39 0.31 0.2 0.28 --break 0.4 --gaps 3 --seed 4 -o "$out/torus-cut.txt"
"$gsd" -v shm surface "$surf_mesh" --curves "$out/torus-cut.txt" -o "$out/surface-phi.npy" \
  --render "$out/surface-phi.png" --isolines "$out/surface-isolines.obj" --colored "$out/surface-phi.ply"
# A loop around the tube bounds nothing (docs/shm-surface.md): the L² distance warps, the L1 one
# jumps on the far side; --filter-nonbounding drops the loop and measures to a small loop beside it.
surf_nb="$out/torus-64.obj"
"$gsd" mesh torus -r 64 -o "$surf_nb"
"$gsd" curve "$surf_nb" --plane 0 1 0 0 --near 0.5 0 0 -o "$out/meridian.txt"
"$gsd" curve "$surf_nb" --sphere 0.2 0.62 0.15 0.2 -o "$out/small-loop.txt"
"$gsd" shm surface "$surf_nb" --curves "$out/meridian.txt" -o "$out/meridian-l2.npy" --render "$out/meridian-l2.png"
"$gsd" -v shm surface "$surf_nb" --curves "$out/meridian.txt" --integrate l1 -o "$out/meridian-l1.npy" \
  --corners "$out/meridian-l1-corners.npy" --jumps "$out/meridian-jumps.obj" --render "$out/meridian-l1.png"
"$gsd" shm surface "$surf_nb" --curves "$out/meridian.txt" "$out/small-loop.txt" --filter-nonbounding \
  -o "$out/filtered.npy" --render "$out/filtered.png"
surf_cloud="$out/torus-cloud.ply"
"$gsd" sample torus -n 20000 --seed 3 -o "$surf_cloud"
"$gsd" curve "$surf_cloud" --sphere 0.5 0 0.2 0.25 --break 0.3 --seed 4 -o "$out/cloud-cut.txt"
"$gsd" -v shm surface "$surf_cloud" --curves "$out/cloud-cut.txt" -o "$out/cloud-phi.npy" --render "$out/cloud-phi.png"

swn_mesh="$out/double-torus.ply"
"$gsd" mesh double-torus -r 72 -o "$swn_mesh"
"$gsd" curve "$swn_mesh" --sphere -0.95 0.35 0.1 0.4 --break 0.3 --seed 2 -o "$out/dt-region.txt"
"$gsd" curve "$swn_mesh" --plane 0 1 0 0 --near 1.2 0 0 --break 0.3 --seed 3 -o "$out/dt-handle-1.txt"
"$gsd" curve "$swn_mesh" --plane 1 1 0 -0.6 --near -0.2 -0.9 0 --break 0.3 --seed 5 -o "$out/dt-handle-2.txt"
dt_curves=("$out/dt-region.txt" "$out/dt-handle-1.txt" "$out/dt-handle-2.txt")
"$gsd" -v swn "$swn_mesh" --curves "${dt_curves[@]}" -o "$out/swn-labels.npy" --w "$out/swn-w.npy" \
  --loops "$out/swn-loops.obj" --render "$out/swn.png"
"$gsd" swn "$swn_mesh" --curves "${dt_curves[@]}" --method shm -o "$out/swn-shm-labels.npy" --render "$out/swn-shm.png"
# A small loop and the outer equator (around the hole), half of each cut away: SWN closes the
# gaps before reading which loop bounds nothing (the default); without, it reads them the wrong way.
gaps_mesh="$out/torus-40.obj"
"$gsd" mesh torus -r 40 -o "$gaps_mesh"
"$gsd" curve "$gaps_mesh" --sphere 0.4 0.45 0.15 0.15 --break 0.5 --reverse 1 --seed 3 -o "$out/gaps-loop.txt"
"$gsd" curve "$gaps_mesh" --plane 0 0 1 0.01 --near 0.7 0 0 --break 0.5 --reverse 1 --seed 13 -o "$out/gaps-equator.txt"
"$gsd" swn "$gaps_mesh" --curves "$out/gaps-loop.txt" "$out/gaps-equator.txt" -o "$out/gaps-labels.npy" \
  --render "$out/swn-gaps-closed.png"
"$gsd" swn "$gaps_mesh" --curves "$out/gaps-loop.txt" "$out/gaps-equator.txt" --no-close-gaps \
  -o "$out/gaps-open-labels.npy" --render "$out/swn-gaps-open.png"

cat <<MSG

demo outputs (input: $cloud, $(head -c 300 "$cloud" | grep -a 'element vertex' | cut -d' ' -f3) points):
  fitted tori          $out/torus.tori
  SDF grid 96^3        $out/sdf.npy           (float32, C order, bounds $bounds)
  SDF gradient         $out/sdf-gradient.npy  (96,96,96,3)
  zero-level mesh      $out/surface.obj
  slices               $out/slice-z.png  $out/slice-y.png
  picture of φ = 0     $out/render.png        (sphere-traced PAT field, shaded by ∇φ)
  SSPD baseline        $out/sspd.npy  $out/sspd-slice-y.png

SHM on a broken mesh (input: $broken, 20% of the area in 3 holes, 10% of faces flipped):
  SDF grid 96^3        $out/shm.npy
  closed zero surface  $out/shm-surface.obj
  slice                $out/shm-slice-z.png
  picture of φ = 0     $out/shm-render.png
  winding number       $out/winding.npy  $out/winding-slice-z.png  (contour at ½: the holes leak)

Fields made of fields: smooth_union(PAT of the cloud, SHM of the broken box offset by -0.3, 0.15):
  grid 96^3            $out/field.npy
  picture of φ = 0     $out/field-render.png
Two scans ($cloud, $scan2): smooth_difference(torus, capsule, 0.04), and the sharp difference's opening by 0.08:
  pictures             $out/scans-difference.png  $out/scans-opening.png

SHM on a surface (input: $surf_mesh and $out/torus-cut.txt, a closed curve with 40% cut away):
  φ per vertex         $out/surface-phi.npy   (float32, the mesh's vertex order)
  picture              $out/surface-phi.png
  isolines             $out/surface-isolines.obj
  colored mesh         $out/surface-phi.ply
  on a point cloud     $out/cloud-phi.npy (φ per point of $surf_cloud), $out/cloud-phi.png
  no inside (a loop around the tube of $surf_nb):
    L² (warped)        $out/meridian-l2.png
    L1 (jumps)         $out/meridian-l1.npy, $out/meridian-l1-corners.npy (per corner), $out/meridian-jumps.obj, $out/meridian-l1.png
    loop left out      $out/filtered.npy, $out/filtered.png (distance to the small loop only)

SWN on a double torus (input: $swn_mesh; a region's boundary and a loop around each handle, 30% cut):
  labels per face      $out/swn-labels.npy    (int32: 1 inside the region, 0 outside)
  w per corner         $out/swn-w.npy
  curve decomposition  $out/swn-loops.obj     (groups bounding, nonbounding, completed)
  pictures             $out/swn.png (SWN)  $out/swn-shm.png (the sign of the surface SHM)
  broken loops, gaps closed (default) or not: $out/swn-gaps-closed.png, $out/swn-gaps-open.png
MSG
