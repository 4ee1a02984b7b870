#include "pumeta/geometry/noise.h"

#include <ATen/ATen.h>
#include <gtest/gtest.h>

#include "pumeta/core/error.h"
#include "pumeta/geometry/sampling.h"
#include "support/test_util.h"

namespace pumeta {
namespace {

/// 100k points with very different spreads per axis (sd about 1.15, 0.29, 0.058).
at::Tensor anisotropic_cloud() {
    return uniform_random_points(100000, 1) * at::tensor({2.f, 0.5f, 0.1f}) +
           at::tensor({5.f, -1.f, 0.f});
}

TEST(RelativeNoise, PerAxisSpreadIsTheCloudsSpreadTimesPercent) {
    at::Tensor points = anisotropic_cloud();
    const at::Tensor cloud_sd = points.to(at::kDouble).std(0, /*unbiased=*/false);
    for (double percent : {0.5, 1.0, 2.0}) {
        at::Tensor noise = (add_relative_noise(points, percent, 7) - points).to(at::kDouble);
        const at::Tensor expected = cloud_sd * percent / 100;
        // The sample sd of 100k normal draws is off by about 0.2 % (one sd); float32 rounding
        // of p + noise (below 1e-6) is negligible against the smallest noise sd (3e-4).
        for (int axis = 0; axis < 3; ++axis) {
            const double sd = noise.select(1, axis).std().item<double>();
            EXPECT_NEAR(sd / expected[axis].item<double>(), 1.0, 0.02)
                << "axis " << axis << " percent " << percent;
            EXPECT_NEAR(noise.select(1, axis).mean().item<double>(), 0.0,
                        0.02 * expected[axis].item<double>());
        }
    }
}

TEST(RelativeNoise, SeededAndValidated) {
    at::Tensor points = anisotropic_cloud().slice(0, 0, 1000);
    EXPECT_TRUE(at::equal(add_relative_noise(points, 1, 3), add_relative_noise(points, 1, 3)));
    EXPECT_FALSE(at::equal(add_relative_noise(points, 1, 3), add_relative_noise(points, 1, 4)));
    EXPECT_TRUE(at::equal(add_relative_noise(points, 0, 3), points));
    EXPECT_THROW(add_relative_noise(points, -1, 3), InputError);
    EXPECT_THROW(add_relative_noise(at::zeros({5, 2}), 1, 3), InputError);
}

TEST(AbsoluteNoise, SpreadIsSigmaWhenClippingIsRare) {
    at::Tensor points = anisotropic_cloud();
    at::Tensor noise = (add_absolute_noise(points, 0.005, 11) - points).to(at::kDouble);
    // Clipping at 6 sigma changes nothing measurable; float32 sums add < 1e-6 absolute.
    for (int axis = 0; axis < 3; ++axis)
        EXPECT_NEAR(noise.select(1, axis).std().item<double>(), 0.005, 0.0002);
}

TEST(AbsoluteNoise, ClippedAtExactlyTheClipValue) {
    // On points at the origin the output is the noise itself, without rounding.
    at::Tensor zeros = at::zeros({100000, 3});
    at::Tensor noise = add_absolute_noise(zeros, 0.02, 12, 0.03);
    EXPECT_EQ(noise.abs().max().item<float>(), 0.03f);
    // P(|N(0, 0.02)| > 0.03) = 13.4 %: hundreds of thousands of draws hit the clip.
    const double clipped = (noise.abs() == 0.03f).to(at::kDouble).mean().item<double>();
    EXPECT_NEAR(clipped, 0.1336, 0.005);
    EXPECT_EQ(add_absolute_noise(zeros, 0.02, 12, 0.01).abs().max().item<float>(), 0.01f);
}

TEST(AbsoluteNoise, SeededAndValidated) {
    at::Tensor points = anisotropic_cloud().slice(0, 0, 1000);
    EXPECT_TRUE(
        at::equal(add_absolute_noise(points, 0.01, 3), add_absolute_noise(points, 0.01, 3)));
    EXPECT_FALSE(
        at::equal(add_absolute_noise(points, 0.01, 3), add_absolute_noise(points, 0.01, 4)));
    EXPECT_THROW(add_absolute_noise(points, -0.01, 3), InputError);
    EXPECT_THROW(add_absolute_noise(points, 0.01, 3, -1), InputError);
}

}  // namespace
}  // namespace pumeta
