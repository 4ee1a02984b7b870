#!/usr/bin/env bash
# Benchmarks with ratios against baselines measured in the same run (medians of 5).
#   scripts/bench.sh foundation   kNN, Chamfer, FPS, Poisson disk, PLY reading (issue: foundation),
#                                 patch extraction of a 300k-point cloud, sparse convolution
#   scripts/bench.sh upsample     whole-cloud 2,048 -> 8,192 upsampling, plain vs adaptation
#   scripts/bench.sh scaling      4x on 100k and 1M points: the midpoint baseline's time in units
#                                 of the network's on the same cloud (target <= 2x at 1M)
#   scripts/bench.sh memory       peak resident memory of `pumeta upsample` on 10k, 100k and 1M
#                                 input points (GNU time), ratio vs the 10k run
#   scripts/bench.sh all
# Run on an idle machine: the script warns when the load average says otherwise. Open3D
# reference rows need `apt-get install libopen3d-dev` before building (optional).
set -euo pipefail
cd "$(dirname "$0")/.."
what=${1:-all}
build=${PUMETA_BUILD_DIR:-build}
out=$(mktemp -d)
trap 'rm -rf "$out"' EXIT
load=$(cut -d' ' -f1 /proc/loadavg)
if awk -v l="$load" 'BEGIN { exit !(l > 0.5) }'; then
    echo "warning: load average $load: timings are not from an idle machine" >&2
fi
run() {  # run NAME BINARY FILTER
    local binary=$build/$2
    if [[ ! -x $binary ]]; then
        echo "($2 not built: skipped)" >&2
        return
    fi
    "$binary" --benchmark_filter="$3" --benchmark_repetitions=5 \
        --benchmark_report_aggregates_only=true --benchmark_format=json \
        > "$out/$1.json" 2> /dev/null
}
if [[ $what == foundation || $what == all ]]; then
    run knn bench_geometry_knn 'BM_(KdTree|Nanoflann)(BuildAndQuery|Query)(/[12])?/real_time'
    run chamfer bench_metrics_chamfer 'BM_Chamfer(Pumeta/threads:1|Nanoflann)$'
    run sampling bench_geometry_sampling 'BM_(FarthestPointSampling/1|PoissonDisk/[12])/real_time'
    run io bench_geometry_io 'ReadPly/binary_le/xyz/1M'
    run patches bench_geometry_patches '.'
    run sparse bench_nn_sparse_conv '(SparseConv3x3x3Forward|DenseGemmSameFlops)/1/'
    run open3d bench_reference_open3d '.'
fi
if [[ $what == upsample || $what == all ]]; then
    run upsample bench_inference_upsample '.'
fi
if [[ $what == scaling || $what == all ]]; then
    # One run each (the network takes a minute and more on 1M points); the binary prints the
    # ratio itself.
    [[ -x $build/bench_inference_large_clouds ]] && "$build/bench_inference_large_clouds" \
        --benchmark_format=console 2> /dev/null
fi
if [[ $what == memory || $what == all ]]; then
    # Inputs: uniform samples of one generated shape; the shipped 4x model, 2 threads.
    mem=$out/memory
    mkdir -p "$mem"
    "$build/pumeta" gen-shapes --count 1 --seed 7 -o "$mem/shape" > /dev/null
    mesh=$(ls "$mem"/shape/*.ply | head -1)
    echo "== peak memory of pumeta upsample, 4x, 2 threads (GNU time, max resident set)"
    base_kb=""
    for n in 10000 100000 1000000; do
        "$build/pumeta" sample "$mesh" -n "$n" --method uniform --seed 1 -o "$mem/in.ply" \
            2> /dev/null
        /usr/bin/time -f "%M %e" -o "$mem/time" "$build/pumeta" --threads 2 upsample \
            "$mem/in.ply" -o "$mem/out.ply" 2> /dev/null > /dev/null
        read -r kb secs < "$mem/time"
        base_kb=${base_kb:-$kb}
        python3 -c "import sys; n, kb, base, s = map(float, sys.argv[1:]); \
arrays = n * 12 * 5 / 2**20; \
print(f'{int(n):>9,d} -> {int(4 * n):>9,d} points  {s:7.1f} s  peak {kb / 1024:7.0f} MiB' \
      f'  ({kb / base:4.2f}x the 10k run; input+output arrays {arrays:5.0f} MiB)')" \
            "$n" "$kb" "$base_kb" "$secs"
        rm -f "$mem/in.ply" "$mem/out.ply"
    done
fi
python3 - "$out" "$what" <<'PY'
import json, os, sys
out, what = sys.argv[1], sys.argv[2]
medians = {}
for name in os.listdir(out):
    if not name.endswith(".json"):
        continue
    with open(os.path.join(out, name)) as f:
        text = f.read()
    if not text.strip():
        continue
    for b in json.loads(text)["benchmarks"]:
        if b.get("aggregate_name") == "median":
            medians[b["run_name"]] = b
def ms(name):
    b = medians.get(name)
    if b is None:
        return None
    scale = {"ns": 1e-6, "us": 1e-3, "ms": 1.0, "s": 1e3}[b["time_unit"]]
    return b["real_time"] * scale
def row(label, ours, base, base_label):
    a, b = ms(ours), ms(base)
    if a is None:
        print(f"{label:46s} (not run)")
        return
    ratio = f"{a / b:5.2f}x {base_label}" if b else "(no baseline in this run)"
    print(f"{label:46s} {a:10.2f} ms   {ratio}")
if what in ("foundation", "all"):
    print("== foundation (median of 5; ratio = pumeta time / baseline time, < 1 is faster)")
    row("kNN k=16, 100k, build+query, 1 thread", "BM_KdTreeBuildAndQuery/1/real_time",
        "BM_NanoflannBuildAndQuery/real_time", "nanoflann")
    row("kNN k=16, 100k, query only, 1 thread", "BM_KdTreeQuery/1/real_time",
        "BM_NanoflannQuery/real_time", "nanoflann")
    row("kNN k=16, 100k, build+query, 2 threads", "BM_KdTreeBuildAndQuery/2/real_time",
        "BM_O3D_KDTreeBuildAndQuery/2/real_time", "Open3D")
    row("CD 8192 x 8192, 1 thread", "BM_ChamferPumeta/threads:1", "BM_ChamferNanoflann", "nanoflann")
    row("FPS 8192 -> 2048", "BM_FarthestPointSampling/1/real_time",
        "BM_O3D_FarthestPointDownSample/real_time", "Open3D")
    row("Poisson disk 100k on 49.6k triangles, 1 thread", "BM_PoissonDisk/1/real_time",
        "BM_O3D_SamplePointsPoissonDisk/iterations:1/real_time", "Open3D")
    row("Poisson disk 100k on 49.6k triangles, 2 threads", "BM_PoissonDisk/2/real_time",
        "BM_O3D_SamplePointsPoissonDisk/iterations:1/real_time", "Open3D")
    row("patches of 300k points, seeds per 70k part", "BM_ExtractPatchesPerPart/real_time",
        "BM_ExtractPatchesWholeCloudFps/real_time", "whole-cloud FPS")
    row("sparse conv 3^3 64->64, 99k sites, 1 thread", "BM_SparseConv3x3x3Forward/1/real_time",
        "BM_DenseGemmSameFlops/1/real_time", "dense GEMM, same FLOPs (target <= 3x)")
    ply = medians.get("ReadPly/binary_le/xyz/1M/real_time")
    if ply:
        print(f"{'read 1M-point binary PLY':46s} {ms('ReadPly/binary_le/xyz/1M/real_time'):10.2f} ms"
              f"   {ply['bytes_per_second'] / 1e6:.0f} MB/s (target >= 100)")
if what in ("upsample", "all"):
    print("== whole-cloud upsampling 2,048 -> 8,192 (median of 5; ratio vs plain in this run)")
    for threads in (1, 2):
        plain = f"BM_Upsample/plain/{threads}/real_time"
        if ms(plain) is None:
            continue
        p = medians[plain]
        print(f"{'plain PU-GCN, ' + str(threads) + ' thread(s)':46s} {ms(plain):10.2f} ms"
              f"   {p['patches_per_s']:.0f} patches/s (target < 500 ms)")
        for n in (1, 5):
            row(f"+ adaptation N={n}, {threads} thread(s)", f"BM_Upsample/tta{n}/{threads}/real_time",
                plain, "plain (target N=5: <= 3x)")
        row(f"midpoint baseline, {threads} thread(s)", f"BM_Midpoint/{threads}/real_time", plain, "plain")
PY
