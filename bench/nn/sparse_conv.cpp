// The sparse engine's convolution: a 3³ convolution 64 -> 64 on about 100k active sites of a
// voxelised sphere (a surface, as PU-Dense's voxels are), against a dense GEMM doing the same
// FLOPs. Compare the "GFLOP/s" counters: useful FLOPs = 2 · pairs · 64 · 64. The argument is
// the thread count (on a shared machine, OpenMP spin-waiting can make 2 threads slower than 1).
// Before the benchmarks, forward + backward is timed against a baseline built from the same
// batched ATen ops (one gather, one bmm, one index_add_) left to autograd's own backward, as
// the engine ran under autograd before its backward was written out, and the ratio printed;
// then, for widths 8 to 128 and PU-Dense's narrowing and widening pairs, both product paths
// (per offset: gather, GEMM, scatter-add; output-major: one gather of every (site, offset) slot
// and one GEMM, or for outputs of 4, 8 or 16 channels the direct kernels of narrow_product.h)
// against three dense GEMMs of the same useful FLOPs, the cost of forward + backward without
// waste.
#include "pumeta/nn/sparse/sparse_conv.h"

#include <ATen/ATen.h>
#include <ATen/Parallel.h>
#include <benchmark/benchmark.h>
#include <torch/csrc/autograd/autograd.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <random>
#include <utility>

#include "pumeta/core/allocator.h"

namespace {

using namespace pumeta;

constexpr int64_t kChannels = 64;

/// The voxels within √3/2 of a sphere of radius 67.5 voxels: about 100k sites.
CoordinateSetPtr sphere_sites() {
    const double radius = 67.5;
    const int64_t extent = int64_t(radius) + 2;
    std::vector<int32_t> flat;
    for (int64_t x = -extent; x <= extent; ++x)
        for (int64_t y = -extent; y <= extent; ++y)
            for (int64_t z = -extent; z <= extent; ++z) {
                double r = std::sqrt(double(x * x + y * y + z * z));
                if (std::abs(r - radius) < 0.5 * std::sqrt(3.0))
                    flat.insert(flat.end(), {0, int32_t(x), int32_t(y), int32_t(z)});
            }
    at::Tensor coords = at::empty({int64_t(flat.size() / 4), 4}, at::kInt);
    std::copy(flat.begin(), flat.end(), coords.data_ptr<int32_t>());
    return CoordinateSet::create(coords, 1);
}

struct Fixture {
    CoordinateSetPtr sites = sphere_sites();
    ParamMap params;
    at::Tensor features;
    int64_t pairs;

    Fixture() {
        std::mt19937_64 rng(1);
        add_sparse_conv(params, "c", kChannels, kChannels, 3, /*bias=*/false, rng);
        at::manual_seed(2);
        features = at::randn({sites->size(), kChannels});
        pairs = sites->conv_map(3, 1)->pairs();
    }
};

const Fixture& fixture() {
    static Fixture instance;
    return instance;
}

void report(benchmark::State& state, double flops) {
    const Fixture& f = fixture();
    state.counters["sites"] = double(f.sites->size());
    state.counters["pairs"] = double(f.pairs);
    state.counters["GFLOP/s"] =
        benchmark::Counter(flops * 1e-9, benchmark::Counter::kIsIterationInvariantRate);
}

void BM_SparseConv3x3x3Forward(benchmark::State& state) {
    at::set_num_threads(int(state.range(0)));
    const Fixture& f = fixture();
    at::NoGradGuard no_grad;
    for (auto _ : state)
        benchmark::DoNotOptimize(sparse_conv(SparseTensor(f.sites, f.features), f.params, "c", {}));
    report(state, 2.0 * double(f.pairs) * kChannels * kChannels);
}

/// Forward and backward to the weight and the features: three times the forward FLOPs.
void BM_SparseConv3x3x3ForwardBackward(benchmark::State& state) {
    at::set_num_threads(int(state.range(0)));
    const Fixture& f = fixture();
    at::Tensor x = f.features.clone().requires_grad_(true);
    const at::Tensor& w = f.params.at("c.weight");
    for (auto _ : state) {
        at::Tensor y = sparse_conv(SparseTensor(f.sites, x), f.params, "c", {}).features();
        benchmark::DoNotOptimize(torch::autograd::grad({y.sum()}, {w, x}));
    }
    report(state, 6.0 * double(f.pairs) * kChannels * kChannels);
}

/// The dense equivalent: one GEMM [pairs, 64] x [64, 64], the same FLOPs as the forward.
void BM_DenseGemmSameFlops(benchmark::State& state) {
    at::set_num_threads(int(state.range(0)));
    const Fixture& f = fixture();
    at::Tensor a = at::randn({f.pairs, kChannels}), b = at::randn({kChannels, kChannels});
    for (auto _ : state) benchmark::DoNotOptimize(a.mm(b));
    report(state, 2.0 * double(f.pairs) * kChannels * kChannels);
}

/// Building the 27-offset kernel map of a fresh coordinate set (hashing + lookups).
void BM_KernelMapBuild(benchmark::State& state) {
    at::set_num_threads(int(state.range(0)));
    const Fixture& f = fixture();
    for (auto _ : state) {
        CoordinateSetPtr fresh = CoordinateSet::create(f.sites->coords(), 1);
        benchmark::DoNotOptimize(fresh->conv_map(3, 1));
    }
    state.counters["sites/s"] =
        benchmark::Counter(double(f.sites->size()), benchmark::Counter::kIsIterationInvariantRate);
}

/// The baseline: the batched product as plain ATen ops in one block, differentiated by
/// autograd itself (which saves every gathered row and scatters whole-input gradients).
at::Tensor autograd_ops_product(const at::Tensor& x, const at::Tensor& w, const KernelMap& map) {
    const int64_t offsets = map.batched_offsets.numel(), rows = map.batched_in.numel() / offsets;
    at::Tensor padded_in = at::cat({x, x.new_zeros({1, x.size(1)})});
    at::Tensor out = at::cat({x.mm(w[map.identity_offset]), x.new_zeros({1, w.size(2)})});
    at::Tensor gathered = padded_in.index_select(0, map.batched_in).view({offsets, rows, -1});
    at::Tensor products = at::bmm(gathered, w.index_select(0, map.batched_offsets));
    return out.index_add(0, map.batched_out, products.view({-1, w.size(2)}))
        .narrow(0, 0, map.output_size);
}

/// Mean seconds of `runs` forward + backward passes of `conv` on one thread, after a warm-up.
template <class Conv>
double seconds_forward_backward(Conv conv, int runs) {
    at::set_num_threads(1);
    const Fixture& f = fixture();
    at::Tensor x = f.features.clone().requires_grad_(true);
    const at::Tensor& w = f.params.at("c.weight");
    auto pass = [&] { torch::autograd::grad({conv(x, w).sum()}, {w, x}); };
    pass();
    auto start = std::chrono::steady_clock::now();
    for (int i = 0; i < runs; ++i) pass();
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count() / runs;
}

BENCHMARK(BM_SparseConv3x3x3Forward)->Arg(1)->Arg(2)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_SparseConv3x3x3ForwardBackward)
    ->Arg(1)
    ->Arg(2)
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();
BENCHMARK(BM_DenseGemmSameFlops)->Arg(1)->Arg(2)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_KernelMapBuild)->Arg(1)->Arg(2)->Unit(benchmark::kMillisecond)->UseRealTime();

/// The map with its output-major tables dropped: the per-offset gather-GEMM-scatter path.
pumeta::KernelMap without_tables(const pumeta::KernelMap& map) {
    pumeta::KernelMap copy = map;
    copy.gather_table = at::Tensor();
    copy.scatter_table = at::Tensor();
    return copy;
}

/// Mean seconds of `runs` dense GEMMs [rows, Cin] x [Cin, Cout] on one thread, after a warm-up.
double seconds_gemm(int64_t rows, int64_t in_channels, int64_t out_channels, int runs) {
    at::set_num_threads(1);
    at::Tensor a = at::randn({rows, in_channels}), b = at::randn({in_channels, out_channels});
    benchmark::DoNotOptimize(a.mm(b));
    auto start = std::chrono::steady_clock::now();
    for (int i = 0; i < runs; ++i) benchmark::DoNotOptimize(a.mm(b));
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count() / runs;
}

/// Forward + backward of a 3³ convolution Cin -> Cout on the sphere's sites through both paths,
/// against three dense GEMMs of the same useful FLOPs (forward, and the two gradients).
void compare_paths(int64_t in_channels, int64_t out_channels) {
    const Fixture& f = fixture();
    const pumeta::KernelMap& map = *f.sites->conv_map(3, 1);
    const pumeta::KernelMap per_offset = without_tables(map);
    std::mt19937_64 rng(3);
    pumeta::ParamMap params;
    pumeta::add_sparse_conv(params, "c", in_channels, out_channels, 3, /*bias=*/false, rng);
    at::manual_seed(4);
    at::Tensor features = at::randn({f.sites->size(), in_channels});
    auto run = [&](const pumeta::KernelMap& m) {
        at::set_num_threads(1);
        at::Tensor x = features.clone().requires_grad_(true);
        const at::Tensor& w = params.at("c.weight");
        auto pass = [&] {
            torch::autograd::grad({pumeta::apply_kernel_map(x, w, {}, m).sum()}, {w, x});
        };
        pass();
        auto start = std::chrono::steady_clock::now();
        for (int i = 0; i < 3; ++i) pass();
        return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count() / 3;
    };
    const double gemms = 3 * seconds_gemm(map.pairs(), in_channels, out_channels, 3);
    const double scattered = run(per_offset);
    const double tabled = map.gather_table.defined() ? run(map) : scattered;
    std::printf(
        "3^3 conv %3lld -> %3lld, %lld pairs (%.0f%% of the slots), 1 thread: three dense GEMMs "
        "%6.1f ms; forward + backward per offset %7.1f ms (%.2fx), output-major %7.1f ms "
        "(%.2fx)\n",
        (long long)in_channels, (long long)out_channels, (long long)map.pairs(),
        100.0 * double(map.pairs()) / double(map.output_size * map.kernel_volume()), 1e3 * gemms,
        1e3 * scattered, scattered / gemms, 1e3 * tabled, tabled / gemms);
}

}  // namespace

int main(int argc, char** argv) {
    // As the CLI runs: freed memory stays in the process (core/allocator.h), for the dense
    // baseline too.
    pumeta::keep_freed_memory();
    benchmark::Initialize(&argc, argv);
    if (benchmark::ReportUnrecognizedArguments(argc, argv)) return 1;
    const pumeta::KernelMap map = without_tables(*fixture().sites->conv_map(3, 1));
    const double baseline = seconds_forward_backward(
        [&](const at::Tensor& x, const at::Tensor& w) { return autograd_ops_product(x, w, map); },
        3);
    const double engine = seconds_forward_backward(
        [&](const at::Tensor& x, const at::Tensor& w) {
            return pumeta::apply_kernel_map(x, w, {}, map);
        },
        3);
    std::printf(
        "3^3 conv 64 -> 64 forward + backward, 1 thread: %.0f ms as ATen ops under autograd, "
        "%.0f ms with the written-out blocked backward (per-offset path): %.2fx\n",
        1e3 * baseline, 1e3 * engine, baseline / engine);
    for (int64_t channels : {8, 16, 32, 64, 128}) compare_paths(channels, channels);
    // PU-Dense's Inception units narrow C -> C/4 and widen C/4 -> C/2 (models/pudense.cpp).
    for (auto [in, out] : {std::pair<int64_t, int64_t>{32, 8}, {64, 16}, {8, 16}, {16, 32}})
        compare_paths(in, out);
    benchmark::RunSpecifiedBenchmarks();
    benchmark::Shutdown();
    return 0;
}
