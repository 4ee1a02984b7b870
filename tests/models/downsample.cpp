#include "pumeta/models/downsample.h"

#include <ATen/ATen.h>
#include <gtest/gtest.h>

#include "pumeta/core/error.h"
#include "pumeta/geometry/sampling.h"
#include "pumeta/models/pugcn.h"

namespace pumeta {

namespace {

at::Tensor cloud(int64_t batch, int64_t n, uint64_t seed) {
    at::Generator gen = at::detail::createCPUGenerator(seed);
    return at::rand({batch, n, 3}, gen);
}

// Index of each row of `subset` [m,3] in `points` [n,3]; -1 when absent.
std::vector<int64_t> find_rows(const at::Tensor& subset, const at::Tensor& points) {
    std::vector<int64_t> found;
    at::Tensor equal = (subset.unsqueeze(1) == points.unsqueeze(0)).all(-1);  // [m,n]
    for (int64_t i = 0; i < subset.size(0); ++i) {
        at::Tensor hits = equal[i].nonzero();
        found.push_back(hits.numel() ? hits[0][0].item<int64_t>() : -1);
    }
    return found;
}

}  // namespace

TEST(DownsamplePoints, EveryMethodKeepsDistinctInputPointsReproducibly) {
    at::Tensor dense = cloud(3, 200, 1);
    for (const char* method : {"fps", "random", "nonuniform"}) {
        SCOPED_TRACE(method);
        at::Tensor sparse = downsample_points(dense, 50, method, 9);
        ASSERT_EQ(sparse.sizes(), (std::vector<int64_t>{3, 50, 3}));
        EXPECT_TRUE(sparse.equal(downsample_points(dense, 50, method, 9)));
        for (int64_t b = 0; b < 3; ++b) {
            std::vector<int64_t> rows = find_rows(sparse[b], dense[b]);
            std::sort(rows.begin(), rows.end());
            EXPECT_GE(rows.front(), 0);
            EXPECT_EQ(std::unique(rows.begin(), rows.end()), rows.end());
        }
    }
    EXPECT_FALSE(downsample_points(dense, 50, "random", 9)
                     .equal(downsample_points(dense, 50, "random", 10)));
}

TEST(DownsamplePoints, FpsIsFarthestPointSampling) {
    at::Tensor dense = cloud(2, 100, 2);
    at::Tensor idx = farthest_point_sampling_batched(dense, 25);
    for (int64_t b = 0; b < 2; ++b)
        EXPECT_TRUE(
            downsample_points(dense, 25, "fps", 0)[b].equal(dense[b].index_select(0, idx[b])));
}

TEST(DownsamplePoints, NonuniformVariesTheDensityMoreThanUniform) {
    // The kept points are drawn from a Gaussian over the rank of the distance to a seed point,
    // so their local spacing (distance to the 5th nearest kept point) varies more than that
    // of a uniform subset. On a flat square, as patches are surfaces.
    at::Tensor dense = cloud(16, 2000, 3);
    dense.select(2, 2).zero_();
    auto spacing_variation = [&](const char* method) {
        at::Tensor sparse = downsample_points(dense, 200, method, 4);
        at::Tensor d = (sparse.unsqueeze(2) - sparse.unsqueeze(1)).pow(2).sum(-1).sqrt();
        at::Tensor fifth = std::get<0>(d.topk(6, -1, /*largest=*/false)).select(-1, 5);
        return (fifth.std(1) / fifth.mean(1)).mean().item<double>();
    };
    double nonuniform = spacing_variation("nonuniform"), uniform = spacing_variation("random");
    EXPECT_GT(nonuniform, 1.2 * uniform);
}

TEST(DownsamplePoints, InvalidRequestsAreInputErrors) {
    at::Tensor dense = cloud(1, 10, 4);
    EXPECT_THROW(downsample_points(dense, 11, "random", 0), InputError);
    EXPECT_THROW(downsample_points(dense, 5, "grid", 0), InputError);
}

TEST(DownsamplePoints, BackboneKeepsOneInRatioWithItsConfiguredMethod) {
    nlohmann::json config = {{"backbone", "pugcn"}, {"ratio", 4}, {"downsampler", "random"}};
    std::unique_ptr<Backbone> model = make_backbone(config);
    at::Tensor dense = cloud(2, 256, 5);
    at::Tensor sparse = model->downsample(dense, 7);
    EXPECT_EQ(sparse.sizes(), (std::vector<int64_t>{2, 64, 3}));
    EXPECT_TRUE(sparse.equal(downsample_points(dense, 64, "random", 7)));
}

}  // namespace pumeta
