// Sparse convolutions against dense 3-D convolutions (at::conv3d / at::conv_transpose3d) on a
// small occupied grid, and their first and second derivatives against finite differences.
#include "pumeta/nn/sparse/sparse_conv.h"

#include <ATen/ATen.h>
#include <gtest/gtest.h>
#include <torch/csrc/autograd/autograd.h>

#include <functional>
#include <random>
#include <set>

#include "pumeta/core/error.h"
#include "pumeta/nn/sparse/sparse_ops.h"

namespace pumeta {
namespace {

constexpr int64_t kBatches = 2;

/// About `percent` % of the voxels of [lo, lo + extent)^3 per batch element, as multiples of
/// `stride`.
CoordinateSetPtr occupied_grid(int64_t lo, int64_t extent, int64_t stride, uint64_t seed,
                               uint64_t percent = 35) {
    std::mt19937_64 rng(seed);
    std::vector<int32_t> flat;
    for (int64_t b = 0; b < kBatches; ++b)
        for (int64_t x = 0; x < extent; ++x)
            for (int64_t y = 0; y < extent; ++y)
                for (int64_t z = 0; z < extent; ++z)
                    if (rng() % 100 < percent)
                        flat.insert(flat.end(),
                                    {int32_t(b), int32_t((lo + x) * stride),
                                     int32_t((lo + y) * stride), int32_t((lo + z) * stride)});
    at::Tensor coords = at::empty({int64_t(flat.size() / 4), 4}, at::kInt);
    std::copy(flat.begin(), flat.end(), coords.data_ptr<int32_t>());
    return CoordinateSet::create(coords, stride);
}

/// A dense grid [B,C,S,S,S] whose voxel i along an axis sits at origin + i·unit.
struct Grid {
    int64_t origin;
    int64_t unit;
    int64_t size;

    at::Tensor index(const CoordinateSet& set) const {
        at::Tensor c = set.coords().to(at::kLong);
        at::Tensor xyz = (c.narrow(1, 1, 3) - origin);
        EXPECT_TRUE((xyz.remainder(unit) == 0).all().item<bool>());
        xyz = xyz.div(unit, "floor");
        EXPECT_TRUE(((xyz >= 0) & (xyz < size)).all().item<bool>()) << "grid too small";
        return c.select(1, 0) * size * size * size +
               (xyz.select(1, 0) * size + xyz.select(1, 1)) * size + xyz.select(1, 2);
    }
    at::Tensor to_dense(const SparseTensor& x) const {
        const int64_t channels = x.channels();
        at::Tensor flat =
            at::zeros({kBatches * size * size * size, channels}, x.features().options());
        flat = flat.index_put({index(*x.coords())}, x.features());
        return flat.view({kBatches, size, size, size, channels}).permute({0, 4, 1, 2, 3});
    }
    /// Rows of a dense [B,C,S,S,S] result at the sites of `set`.
    at::Tensor at_sites(const at::Tensor& dense, const CoordinateSet& set) const {
        EXPECT_EQ(dense.size(2), size);
        at::Tensor flat = dense.permute({0, 2, 3, 4, 1}).reshape({-1, dense.size(1)});
        return flat.index_select(0, index(set));
    }
};

/// [K³,Cin,Cout] -> conv3d's [Cout,Cin,K,K,K] and conv_transpose3d's [Cin,Cout,K,K,K].
at::Tensor dense_weight(const at::Tensor& w, int64_t k) {
    return w.permute({2, 1, 0}).reshape({w.size(2), w.size(1), k, k, k});
}
at::Tensor dense_weight_transposed(const at::Tensor& w, int64_t k) {
    return w.permute({1, 2, 0}).reshape({w.size(1), w.size(2), k, k, k});
}

ParamMap conv_params(int64_t in, int64_t out, int64_t k, bool bias, uint64_t seed,
                     at::ScalarType dtype = at::kFloat) {
    ParamMap params;
    std::mt19937_64 rng(seed);
    add_sparse_conv(params, "c", in, out, k, bias, rng);
    for (auto& [name, p] : params) p = p.detach().to(dtype).requires_grad_(true);
    return params;
}

SparseTensor random_features(const CoordinateSetPtr& set, int64_t channels, uint64_t seed,
                             at::ScalarType dtype = at::kFloat) {
    at::manual_seed(seed);
    return SparseTensor(set, at::randn({set->size(), channels}, at::TensorOptions(dtype)));
}

void expect_close(const at::Tensor& a, const at::Tensor& b, double tolerance = 1e-4) {
    ASSERT_EQ(a.sizes(), b.sizes());
    double scale = b.abs().max().item<double>() + 1e-12;
    EXPECT_LT((a - b).abs().max().item<double>() / scale, tolerance);
}

TEST(SparseConv, StrideOneMatchesDenseConv3dForKernelsAndDilations) {
    auto set = occupied_grid(-4, 10, 1, 1);
    // 3 -> 4 channels moves rows element-wise, 24 -> 20 row by row (see sparse_conv.cpp).
    for (auto [k, dilation, in, out] :
         {std::tuple{1, 1, 3, 4}, std::tuple{3, 1, 3, 4}, std::tuple{5, 1, 3, 4},
          std::tuple{3, 2, 3, 4}, std::tuple{3, 1, 24, 20}, std::tuple{5, 2, 24, 20}}) {
        SparseTensor x = random_features(set, in, 2);
        ParamMap params = conv_params(in, out, k, /*bias=*/true, 3);
        SparseTensor y = sparse_conv(x, params, "c", {k, 1, dilation});
        EXPECT_EQ(y.coords(), set);
        const int64_t pad = dilation * (k - 1) / 2;
        Grid grid{-4 - pad, 1, 10 + 2 * pad};
        at::Tensor dense = at::conv3d(grid.to_dense(x), dense_weight(params["c.weight"], k),
                                      params["c.bias"], 1, pad, dilation);
        expect_close(y.features(), grid.at_sites(dense, *set));
    }
}

TEST(SparseConv, StrideTwoMatchesDenseConv3dAtTheCoarseSites) {
    // From stride 1 and, one level down, from stride 2 (offsets in input strides).
    for (int64_t unit : {1, 2}) {
        auto set = occupied_grid(-4, 10, unit, 4 + unit);
        SparseTensor x = random_features(set, 3, 5);
        ParamMap params = conv_params(3, 2, 3, /*bias=*/false, 6);
        SparseTensor y = sparse_conv(x, params, "c", {3, 2, 1});
        EXPECT_EQ(y.stride(), 2 * unit);
        EXPECT_EQ(y.coords(), set->coarser(2));
        Grid fine{-8 * unit, unit, 18};  // origin a multiple of the output stride
        at::Tensor dense =
            at::conv3d(fine.to_dense(x), dense_weight(params["c.weight"], 3), {}, 2, 1);
        Grid coarse{-8 * unit, 2 * unit, dense.size(2)};
        expect_close(y.features(), coarse.at_sites(dense, *y.coords()));
    }
}

TEST(SparseConv, TransposedMatchesDenseConvTranspose3dAtTheFineSites) {
    auto fine = occupied_grid(-4, 10, 1, 7);
    auto coarse_set = fine->coarser(2);
    SparseTensor coarse = random_features(coarse_set, 4, 8);
    ParamMap params = conv_params(4, 3, 3, /*bias=*/true, 9);
    SparseTensor y = sparse_conv_transpose(coarse, fine, params, "c", 3);
    EXPECT_EQ(y.coords(), fine);
    Grid coarse_grid{-8, 2, 9};
    at::Tensor dense = at::conv_transpose3d(coarse_grid.to_dense(coarse),
                                            dense_weight_transposed(params["c.weight"], 3),
                                            params["c.bias"], 2, 1);
    Grid fine_grid{-8, 1, dense.size(2)};
    expect_close(y.features(), fine_grid.at_sites(dense, *fine));
    // Only the set the input came from is a valid target.
    EXPECT_THROW(sparse_conv_transpose(coarse, occupied_grid(-4, 10, 1, 70), params, "c", 3),
                 InputError);
}

TEST(SparseConv, GenerativeMatchesDenseConvTranspose3dEverywhere) {
    auto coarse_set = occupied_grid(-2, 5, 2, 10);
    SparseTensor coarse = random_features(coarse_set, 3, 11);
    ParamMap params = conv_params(3, 2, 5, /*bias=*/false, 12);
    SparseTensor y = sparse_conv_generative(coarse, params, "c", 5);
    EXPECT_EQ(y.stride(), 1);
    Grid coarse_grid{-8, 2, 9};
    at::Tensor dense = at::conv_transpose3d(
        coarse_grid.to_dense(coarse), dense_weight_transposed(params["c.weight"], 5), {}, 2, 2);
    Grid fine_grid{-8, 1, dense.size(2)};
    expect_close(y.features(), fine_grid.at_sites(dense, *y.coords()));
    // Nothing outside the generated sites: the dense result vanishes there.
    at::Tensor outside = fine_grid.to_dense(y) - dense;
    EXPECT_LT(outside.abs().max().item<double>(), 1e-4 * dense.abs().max().item<double>());
}

/// The ops under test as functions of (weight, features).
using Op = std::function<at::Tensor(const at::Tensor& weight, const at::Tensor& features)>;

struct Case {
    const char* name;
    Op op;
    at::Tensor weight, features;
};

std::vector<Case> derivative_cases() {
    auto fine = occupied_grid(-2, 5, 1, 20);
    auto coarse = fine->coarser(2);
    std::vector<Case> cases;
    auto add = [&](const char* name, int64_t k, const CoordinateSetPtr& in_set,
                   std::function<SparseTensor(const SparseTensor&, const ParamMap&)> f,
                   int64_t channels = 2) {
        ParamMap params = conv_params(channels, channels, k, false, 21, at::kDouble);
        SparseTensor x = random_features(in_set, channels, 22, at::kDouble);
        Op op = [f, in_set](const at::Tensor& w, const at::Tensor& feats) {
            return f(SparseTensor(in_set, feats), ParamMap{{"c.weight", w}}).features();
        };
        cases.push_back({name, op, params["c.weight"], x.features()});
    };
    add("dilated", 3, fine, [](const SparseTensor& x, const ParamMap& p) {
        return sparse_conv(x, p, "c", {3, 1, 2});
    });
    add("strided", 3, fine, [](const SparseTensor& x, const ParamMap& p) {
        return sparse_conv(x, p, "c", {3, 2, 1});
    });
    add("transposed", 3, coarse, [fine](const SparseTensor& x, const ParamMap& p) {
        return sparse_conv_transpose(x, fine, p, "c", 3);
    });
    add("generative", 3, coarse, [](const SparseTensor& x, const ParamMap& p) {
        return sparse_conv_generative(x, p, "c", 3);
    });
    add(
        "wide", 3, fine,
        [](const SparseTensor& x, const ParamMap& p) {
            return sparse_conv(x, p, "c", {3, 1, 1});
        },
        16);
    // The per-offset path that large sparse maps take.
    add("per-offset", 3, fine, [](const SparseTensor& x, const ParamMap& p) {
        KernelMap map = *x.coords()->conv_map(3, 1);
        map.batched_offsets = map.batched_in = map.batched_out = at::Tensor();
        map.gather_table = map.scatter_table = at::Tensor();
        return x.with_features(apply_kernel_map(x.features(), p.at("c.weight"), {}, map));
    });
    // The batched path that small sparse maps take.
    add("batched", 3, fine, [](const SparseTensor& x, const ParamMap& p) {
        KernelMap map = *x.coords()->conv_map(3, 1);
        map.gather_table = map.scatter_table = at::Tensor();
        return x.with_features(apply_kernel_map(x.features(), p.at("c.weight"), {}, map));
    });
    return cases;
}

/// A nonlinear scalar of the op's output, so that second derivatives do not vanish.
at::Tensor objective(const Case& c, const at::Tensor& w, const at::Tensor& x) {
    at::Tensor y = c.op(w, x);
    at::Tensor r = at::linspace(-1, 1, y.numel(), y.options()).view(y.sizes());
    return (at::tanh(y) * r).sum();
}

TEST(SparseConv, GradientsMatchFiniteDifferences) {
    for (const Case& c : derivative_cases()) {
        at::Tensor w = c.weight.detach().requires_grad_(true);
        at::Tensor x = c.features.detach().requires_grad_(true);
        auto grads = torch::autograd::grad({objective(c, w, x)}, {w, x});
        at::manual_seed(30);
        at::Tensor dw = at::randn_like(w), dx = at::randn_like(x);
        double analytic = ((grads[0] * dw).sum() + (grads[1] * dx).sum()).item<double>();
        const double eps = 1e-6;
        at::NoGradGuard no_grad;
        double numeric = (objective(c, w + eps * dw, x + eps * dx).item<double>() -
                          objective(c, w - eps * dw, x - eps * dx).item<double>()) /
                         (2 * eps);
        EXPECT_NEAR(analytic, numeric, 1e-6 * std::max(1.0, std::abs(numeric))) << c.name;
    }
}

TEST(SparseConv, SecondDerivativesMatchFiniteDifferences) {
    for (const Case& c : derivative_cases()) {
        at::manual_seed(31);
        at::Tensor uw = at::randn_like(c.weight), ux = at::randn_like(c.features);
        at::Tensor vw = at::randn_like(c.weight), vx = at::randn_like(c.features);
        // s(w, x) = <∇L(w, x), u>; its gradient is the Hessian times u.
        auto directional = [&](const at::Tensor& w0, const at::Tensor& x0, bool graph) {
            at::Tensor w = w0.detach().requires_grad_(true);
            at::Tensor x = x0.detach().requires_grad_(true);
            auto g = torch::autograd::grad({objective(c, w, x)}, {w, x}, {}, graph, graph);
            return std::tuple{(g[0] * uw).sum() + (g[1] * ux).sum(), w, x};
        };
        auto [s, w, x] = directional(c.weight, c.features, true);
        auto hu = torch::autograd::grad({s}, {w, x});
        double analytic = ((hu[0] * vw).sum() + (hu[1] * vx).sum()).item<double>();
        const double eps = 1e-5;
        double plus = std::get<0>(directional(c.weight + eps * vw, c.features + eps * vx, false))
                          .item<double>();
        double minus = std::get<0>(directional(c.weight - eps * vw, c.features - eps * vx, false))
                           .item<double>();
        double numeric = (plus - minus) / (2 * eps);
        EXPECT_GT(std::abs(numeric), 1e-6) << c.name << ": degenerate second derivative";
        EXPECT_NEAR(analytic, numeric, 1e-6 * std::max(1.0, std::abs(numeric))) << c.name;
    }
}

TEST(SparseConv, BatchedAndPerOffsetPathsAgree) {
    auto fine = occupied_grid(-4, 10, 1, 60);
    auto coarse = fine->coarser(2);
    const std::pair<const char*, std::shared_ptr<const KernelMap>> maps[] = {
        {"conv", fine->conv_map(3, 1)},
        {"dilated", fine->conv_map(3, 2)},
        {"down", fine->down_map(3, 2)},
        {"transposed", std::make_shared<const KernelMap>(fine->down_map(3, 2)->transposed())},
        {"generative", coarse->generated(5, 2).map}};
    for (const auto& [name, map] : maps) {
        ASSERT_TRUE(map->batched_offsets.defined()) << name << ": small maps run batched";
        KernelMap batched_map = *map;
        batched_map.gather_table = batched_map.scatter_table = at::Tensor();
        KernelMap loop = batched_map;
        loop.batched_offsets = loop.batched_in = loop.batched_out = at::Tensor();
        at::manual_seed(61);
        at::Tensor x = at::randn({map->input_size, 3}).requires_grad_(true);
        at::Tensor w = at::randn({map->kernel_volume(), 3, 2}).requires_grad_(true);
        at::Tensor b = at::randn({2});
        at::Tensor batched = apply_kernel_map(x, w, b, batched_map);
        at::Tensor looped = apply_kernel_map(x, w, b, loop);
        expect_close(batched, looped, 1e-5);
        at::Tensor r = at::randn_like(batched);
        auto g1 = torch::autograd::grad({(batched * r).sum()}, {x, w});
        auto g2 = torch::autograd::grad({(looped * r).sum()}, {x, w});
        expect_close(g1[0], g2[0], 1e-5);
        expect_close(g1[1], g2[1], 1e-5);
    }
}

TEST(SparseConv, OutputMajorAndPerOffsetPathsAgree) {
    auto fine = occupied_grid(-4, 10, 1, 60, /*percent=*/70);
    auto coarse = fine->coarser(2);
    const std::pair<const char*, std::shared_ptr<const KernelMap>> maps[] = {
        {"conv", fine->conv_map(3, 1)},
        {"dilated", fine->conv_map(3, 2)},
        {"down", fine->down_map(3, 2)},
        {"transposed", std::make_shared<const KernelMap>(fine->down_map(3, 2)->transposed())},
        {"generative", coarse->generated(5, 2).map}};
    int64_t tabled = 0;
    for (const auto& [name, map] : maps) {
        if (!map->gather_table.defined()) continue;
        ++tabled;
        ASSERT_EQ(map->gather_table.sizes(),
                  (at::IntArrayRef{map->output_size, map->kernel_volume()}));
        ASSERT_EQ(map->scatter_table.sizes(),
                  (at::IntArrayRef{map->input_size, map->kernel_volume()}));
        KernelMap loop = *map;
        loop.gather_table = loop.scatter_table = at::Tensor();
        loop.batched_offsets = loop.batched_in = loop.batched_out = at::Tensor();
        // Output widths 5 (gather + GEMM) and 8 (the direct narrow kernels).
        for (auto [channels, width] :
             {std::pair<int64_t, int64_t>{3, 5}, {24, 5}, {3, 8}, {24, 8}}) {
            at::manual_seed(64);
            at::Tensor x = at::randn({map->input_size, channels}).requires_grad_(true);
            at::Tensor w = at::randn({map->kernel_volume(), channels, width}).requires_grad_(true);
            at::Tensor b = at::randn({width});
            at::Tensor tables = apply_kernel_map(x, w, b, *map);
            at::Tensor looped = apply_kernel_map(x, w, b, loop);
            expect_close(tables, looped, 1e-4);
            at::Tensor r = at::randn_like(tables);
            auto g1 = torch::autograd::grad({(tables * r).sum()}, {x, w});
            auto g2 = torch::autograd::grad({(looped * r).sum()}, {x, w});
            expect_close(g1[0], g2[0], 1e-4);
            expect_close(g1[1], g2[1], 1e-4);
        }
    }
    // The grid is dense enough that stride-1 maps fill most of their slots.
    EXPECT_GE(tabled, 2);
}

/// Σ_k out[map.out[k]] += x[map.in[k]] · W_k with one plain ATen op per step, differentiated
/// by autograd itself: the reference for the blocked convolution and its written-out backward.
at::Tensor reference_product(const at::Tensor& x, const at::Tensor& w, const KernelMap& map) {
    at::Tensor out = at::zeros({map.output_size, w.size(2)}, x.options());
    for (int64_t k = 0; k < map.kernel_volume(); ++k)
        out = out.index_add(0, map.out[k], x.index_select(0, map.in[k]).mm(w[k]));
    return out;
}

TEST(SparseConv, RowBlocksGiveTheUnblockedValuesAndGradients) {
    // 64 channels: blocks of 2^18 / (offsets · 64) rows (157 for 26 offsets); more rows here.
    auto fine = occupied_grid(-6, 12, 1, 62);
    const std::pair<const char*, std::shared_ptr<const KernelMap>> maps[] = {
        {"conv", fine->conv_map(3, 1)},
        {"transposed", std::make_shared<const KernelMap>(fine->down_map(3, 2)->transposed())}};
    for (auto [name, map] : maps) {
        ASSERT_TRUE(map->batched_offsets.defined()) << name;
        // The per-offset blocks (the output-major path blocks by rows too and is compared
        // with them in OutputMajorAndPerOffsetPathsAgree).
        KernelMap per_offset = *map;
        per_offset.gather_table = per_offset.scatter_table = at::Tensor();
        map = std::make_shared<const KernelMap>(per_offset);
        const int64_t offsets = map->batched_offsets.numel();
        ASSERT_GT(map->batched_in.numel() / offsets, (int64_t(1) << 18) / (offsets * 64)) << name;
        at::manual_seed(63);
        at::Tensor x = at::randn({map->input_size, 64}).requires_grad_(true);
        at::Tensor w = at::randn({map->kernel_volume(), 64, 64}).requires_grad_(true);
        at::Tensor r = at::randn({map->output_size, 64});
        at::Tensor blocked = apply_kernel_map(x, w, {}, *map);
        at::Tensor reference = reference_product(x, w, *map);
        expect_close(blocked.detach(), reference.detach(), 1e-4);
        auto g = torch::autograd::grad({(blocked * r).sum()}, {x, w});
        auto g_ref = torch::autograd::grad({(reference * r).sum()}, {x, w});
        expect_close(g[0], g_ref[0], 1e-4);
        expect_close(g[1], g_ref[1], 1e-4);
        at::NoGradGuard no_grad;
        expect_close(apply_kernel_map(x, w, {}, *map), reference.detach(), 1e-4);
    }
}

TEST(SparseConv, LayersOnTheSameSitesShareOneKernelMap) {
    auto set = occupied_grid(0, 6, 1, 40);
    SparseTensor x = random_features(set, 2, 41);
    ParamMap a = conv_params(2, 2, 3, true, 42), b = conv_params(2, 2, 3, true, 43);
    SparseTensor y = sparse_conv(x, a, "c", {3, 1, 1});
    EXPECT_EQ(set->kernel_maps_built(), 1);
    sparse_conv(y, b, "c", {3, 1, 1});  // y lives on the same set
    sparse_conv(x, b, "c", {3, 1, 1});
    EXPECT_EQ(set->kernel_maps_built(), 1);
    sparse_conv(x, b, "c", {3, 1, 2});  // another dilation: a second map
    EXPECT_EQ(set->kernel_maps_built(), 2);
}

TEST(SparseConv, RejectsMismatchedWeights) {
    auto set = occupied_grid(0, 4, 1, 50);
    SparseTensor x = random_features(set, 2, 51);
    ParamMap params = conv_params(3, 2, 3, false, 52);  // expects 3 input channels
    EXPECT_THROW(sparse_conv(x, params, "c", {3, 1, 1}), InputError);
    ParamMap right = conv_params(2, 2, 3, false, 53);
    EXPECT_THROW(sparse_conv(x, right, "c", {5, 1, 1}), InputError);
    EXPECT_THROW(sparse_conv(x, right, "c", {3, 2, 2}), InputError);
}

}  // namespace
}  // namespace pumeta
