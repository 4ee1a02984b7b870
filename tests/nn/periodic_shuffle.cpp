#include "pumeta/nn/periodic_shuffle.h"

#include <ATen/ATen.h>
#include <gtest/gtest.h>

#include "pumeta/core/error.h"

namespace pumeta {

TEST(PeriodicShuffle, ChildrenOfAPointAreConsecutiveAndTakeInterleavedChannels) {
    const int64_t batch = 2, points = 5, channels = 3, r = 4;
    // Encode (b, i, channel index) in each value to check where it lands.
    at::Tensor x = at::empty({batch, points, channels * r}, at::kDouble);
    for (int64_t b = 0; b < batch; ++b)
        for (int64_t i = 0; i < points; ++i)
            for (int64_t q = 0; q < channels * r; ++q) x[b][i][q] = 1000 * b + 100 * i + q;
    at::Tensor y = periodic_shuffle(x, r);
    ASSERT_EQ(y.sizes(), (std::vector<int64_t>{batch, points * r, channels}));
    for (int64_t b = 0; b < batch; ++b)
        for (int64_t i = 0; i < points; ++i)
            for (int64_t s = 0; s < r; ++s)
                for (int64_t c = 0; c < channels; ++c)
                    EXPECT_EQ(y[b][i * r + s][c].item<double>(), 1000 * b + 100 * i + c * r + s);
}

TEST(PeriodicShuffle, RatioOneIsIdentityAndIndivisibleChannelsAreRejected) {
    at::Tensor x = at::rand({1, 4, 6});
    EXPECT_TRUE(periodic_shuffle(x, 1).equal(x));
    EXPECT_THROW(periodic_shuffle(x, 4), InputError);
}

}  // namespace pumeta
