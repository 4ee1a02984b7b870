#!/usr/bin/env bash
# The main job on a fresh machine: install, build, fetch an example (the Stanford bunny scan
# from Debian's CGAL data), upsample it 4x with the shipped PU-GCN (plain and meta-trained with
# test-time adaptation), print metrics next to the midpoint baseline, write pictures to demo/.
set -euo pipefail
cd "$(dirname "$0")/.."
scripts/setup.sh
# The CLI alone: the tests and benchmarks are built by scripts/test.sh.
PUMETA_BUILD_TARGETS=pumeta_cli scripts/build.sh
scripts/get-data.sh
pumeta=build/pumeta
out=demo
mkdir -p "$out"
mesh=data/raw/cgal/data/meshes/bunny00.off

# A sparse input and an independent dense ground truth from the same surface.
$pumeta sample "$mesh" -n 2048 --seed 1 -o "$out/input.ply"
$pumeta sample "$mesh" -n 8192 --seed 2 -o "$out/gt.ply"

# The shipped PU-GCN, then the meta-trained one, which adapts to this input first (paper
# Algorithm 2, its own N and learned step sizes), and the non-learned midpoint baseline.
model=${PUMETA_MODEL:-models/pugcn-x4.pt}
meta=${PUMETA_META_MODEL:-models/pugcn-x4-meta.pt}
$pumeta upsample "$out/input.ply" -o "$out/pugcn.ply" --model "$model" --json
$pumeta upsample "$out/input.ply" -o "$out/pugcn-meta.ply" --model "$meta" --json
$pumeta upsample "$out/input.ply" -o "$out/midpoint.ply" --method midpoint --ratio 4 --json

echo "== metrics against a dense GT sample (lower CD/HD/P2F and higher PSNR are better)"
for name in input midpoint pugcn pugcn-meta; do
    printf '%-11s ' "$name"
    $pumeta metrics "$out/$name.ply" "$out/gt.ply" --mesh "$mesh" --json
done
echo "== pictures in $out/"
$pumeta render "$out/input.ply" "$out/midpoint.ply" "$out/pugcn.ply" "$out/pugcn-meta.ply" \
    "$out/gt.ply" -o "$out/side-by-side.png"
$pumeta render "$out/pugcn-meta.ply" --error-to "$out/gt.ply" -o "$out/error.png"
ls "$out"/*.png
