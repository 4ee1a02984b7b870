#!/usr/bin/env bash
# The main job on a fresh machine: install, build, fetch an example (the Stanford bunny scan
# from Debian's CGAL data), upsample it 4x with the shipped PU-GCN, print its metrics next to
# the midpoint baseline, and write pictures to demo/.
set -euo pipefail
cd "$(dirname "$0")/.."
scripts/setup.sh
scripts/build.sh
scripts/get-data.sh
pumeta=build/pumeta
out=demo
mkdir -p "$out"
mesh=data/raw/cgal/data/meshes/bunny00.off

# A sparse input and an independent dense ground truth from the same surface.
$pumeta sample "$mesh" -n 2048 --seed 1 -o "$out/input.ply"
$pumeta sample "$mesh" -n 8192 --seed 2 -o "$out/gt.ply"

model=${PUMETA_MODEL:-models/pugcn-x4.pt}
$pumeta upsample "$out/input.ply" -o "$out/pugcn.ply" --model "$model" --json
$pumeta upsample "$out/input.ply" -o "$out/pugcn-tta.ply" --model "$model" --tta-steps 5 \
    --tta-lr 1e-3 --json

$pumeta upsample "$out/input.ply" -o "$out/midpoint.ply" --method midpoint --ratio 4 --json

echo "== metrics (GT frame; lower CD/HD/P2F and higher PSNR are better)"
for name in input midpoint pugcn pugcn-tta; do
    printf '%-10s ' "$name"
    $pumeta metrics "$out/$name.ply" "$out/gt.ply" --mesh "$mesh" --json
done
echo "== pictures in $out/"
$pumeta render "$out/input.ply" "$out/pugcn.ply" "$out/gt.ply" -o "$out/side-by-side.png"
$pumeta render "$out/pugcn.ply" --error-to "$out/gt.ply" -o "$out/error.png"
ls "$out"/*.png
