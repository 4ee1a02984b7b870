// The direct narrow kernels against a brute-force oracle in double precision on random tables
// with empty slots, and their independence of the thread count.
#include "pumeta/nn/sparse/narrow_product.h"

#include <ATen/ATen.h>
#include <ATen/Parallel.h>
#include <gtest/gtest.h>

#include <random>

#include "pumeta/core/error.h"

namespace pumeta {
namespace {

/// int32 [rows, volume] with entries in [0, inputs) or -1 (about `empty_percent` % of them).
at::Tensor random_table(int64_t rows, int64_t volume, int64_t inputs, int empty_percent,
                        uint64_t seed) {
    std::mt19937_64 rng(seed);
    at::Tensor table = at::empty({rows, volume}, at::kInt);
    int32_t* t = table.data_ptr<int32_t>();
    for (int64_t i = 0; i < rows * volume; ++i)
        t[i] = int(rng() % 100) < empty_percent ? -1 : int32_t(rng() % uint64_t(inputs));
    return table;
}

/// Σ_k x[table[o, k]] · w[k] with loops in double.
at::Tensor oracle_product(const at::Tensor& x, const at::Tensor& w, const at::Tensor& table) {
    auto xa = x.to(at::kDouble), wa = w.to(at::kDouble);
    auto xs = xa.accessor<double, 2>();
    auto ws = wa.accessor<double, 3>();
    auto ts = table.accessor<int32_t, 2>();
    at::Tensor out = at::zeros({table.size(0), w.size(2)}, at::kDouble);
    auto os = out.accessor<double, 2>();
    for (int64_t o = 0; o < table.size(0); ++o)
        for (int64_t k = 0; k < table.size(1); ++k) {
            if (ts[o][k] < 0) continue;
            for (int64_t c = 0; c < x.size(1); ++c)
                for (int64_t j = 0; j < w.size(2); ++j) os[o][j] += xs[ts[o][k]][c] * ws[k][c][j];
        }
    return out;
}

/// Σ_o x[table[o, k]]ᵀ · g[o] per k, with loops in double.
at::Tensor oracle_weight_gradient(const at::Tensor& x, const at::Tensor& g,
                                  const at::Tensor& table) {
    auto xa = x.to(at::kDouble), ga = g.to(at::kDouble);
    auto xs = xa.accessor<double, 2>();
    auto gs = ga.accessor<double, 2>();
    auto ts = table.accessor<int32_t, 2>();
    at::Tensor sum = at::zeros({table.size(1), x.size(1), g.size(1)}, at::kDouble);
    auto ss = sum.accessor<double, 3>();
    for (int64_t o = 0; o < table.size(0); ++o)
        for (int64_t k = 0; k < table.size(1); ++k) {
            if (ts[o][k] < 0) continue;
            for (int64_t c = 0; c < x.size(1); ++c)
                for (int64_t j = 0; j < g.size(1); ++j) ss[k][c][j] += xs[ts[o][k]][c] * gs[o][j];
        }
    return sum;
}

void expect_close(const at::Tensor& a, const at::Tensor& b, double tol) {
    ASSERT_EQ(a.sizes(), b.sizes());
    const double error = (a.to(at::kDouble) - b.to(at::kDouble)).abs().max().item<double>();
    const double scale = b.abs().max().item<double>();
    EXPECT_LE(error, tol * std::max(1.0, scale)) << "max error " << error << " at scale " << scale;
}

TEST(NarrowProduct, ServesNarrowFloatProducts) {
    for (int64_t width : {4, 8, 16}) EXPECT_TRUE(narrow_kernels_serve(16, width, at::kFloat));
    for (int64_t width : {1, 5, 12, 32}) EXPECT_FALSE(narrow_kernels_serve(8, width, at::kFloat));
    EXPECT_FALSE(narrow_kernels_serve(32, 8, at::kFloat));
    EXPECT_FALSE(narrow_kernels_serve(8, 8, at::kDouble));
}

TEST(NarrowProduct, ProductAndWeightGradientMatchTheOracle) {
    // 9,000 rows: the weight gradient sums over three chunks of rows.
    for (auto [cin, cout] : {std::pair<int64_t, int64_t>{3, 4}, {8, 8}, {16, 16}, {24, 8}}) {
        SCOPED_TRACE(testing::Message() << cin << " -> " << cout);
        const int64_t rows = 9000, inputs = 7000, volume = 27;
        at::Tensor table = random_table(rows, volume, inputs, 40, uint64_t(cin * 100 + cout));
        at::manual_seed(cin + cout);
        at::Tensor x = at::randn({inputs, cin});
        at::Tensor w = at::randn({volume, cin, cout});
        at::Tensor g = at::randn({rows, cout});
        expect_close(narrow_table_product(x, w, table), oracle_product(x, w, table), 1e-5);
        expect_close(narrow_table_weight_gradient(x, g, table), oracle_weight_gradient(x, g, table),
                     1e-5);
    }
}

TEST(NarrowProduct, AnEmptyRowGivesZerosAndNonContiguousInputsAreRead) {
    at::Tensor table = random_table(50, 27, 30, 30, 5);
    table[7].fill_(-1);
    at::manual_seed(3);
    at::Tensor x = at::randn({8, 30}).t();  // [30, 8], not contiguous
    at::Tensor w = at::randn({27, 8, 8});
    at::Tensor out = narrow_table_product(x, w, table);
    EXPECT_TRUE(out[7].eq(0).all().item<bool>());
    expect_close(out, oracle_product(x.contiguous(), w, table), 1e-5);
}

TEST(NarrowProduct, ResultsDoNotDependOnTheThreadCount) {
    at::Tensor table = random_table(20000, 27, 15000, 40, 11);
    at::manual_seed(12);
    at::Tensor x = at::randn({15000, 8}), w = at::randn({27, 8, 8}), g = at::randn({20000, 8});
    const int threads = at::get_num_threads();
    at::set_num_threads(1);
    at::Tensor out1 = narrow_table_product(x, w, table);
    at::Tensor grad1 = narrow_table_weight_gradient(x, g, table);
    at::set_num_threads(2);
    at::Tensor out2 = narrow_table_product(x, w, table);
    at::Tensor grad2 = narrow_table_weight_gradient(x, g, table);
    at::set_num_threads(threads);
    // Same code path, same summation order per row and per chunk: identical bits.
    EXPECT_TRUE(out1.equal(out2));
    EXPECT_TRUE(grad1.equal(grad2));
}

TEST(NarrowProduct, AWidthWithoutAKernelIsAnInternalError) {
    at::Tensor table = random_table(4, 27, 4, 0, 1);
    EXPECT_THROW(narrow_table_product(at::ones({4, 3}), at::ones({27, 3, 5}), table),
                 InternalError);
}

}  // namespace
}  // namespace pumeta
