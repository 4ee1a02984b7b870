#include "pumeta/render/plot.h"

#include <gtest/gtest.h>

#include "pumeta/core/error.h"

namespace pumeta {
namespace {

TEST(NiceTicks, StepsOfOneTwoOrFiveTimesAPowerOfTenCoveringTheRange) {
    EXPECT_EQ(nice_ticks(0, 10, 5), (std::vector<double>{0, 2, 4, 6, 8, 10}));
    std::vector<double> small = nice_ticks(5.61e-4, 5.68e-4, 5);
    ASSERT_GE(small.size(), 3u);
    double step = small[1] - small[0];
    EXPECT_NEAR(step, 2e-6, 1e-12);
    EXPECT_GE(small.front(), 5.61e-4 - 1e-12);
    EXPECT_LE(small.back(), 5.68e-4 + 1e-12);
    EXPECT_EQ(nice_ticks(3, 3).size(), 1u);
}

int count_color(const Image& image, std::array<uint8_t, 3> color) {
    int n = 0;
    for (int y = 0; y < image.height; ++y)
        for (int x = 0; x < image.width; ++x)
            n += std::equal(color.begin(), color.end(), image.pixel(x, y));
    return n;
}

TEST(LinePlot, EachSeriesIsDrawnInItsOwnColourAndMismatchedSeriesAreRejected) {
    LinePlot plot{"title", "x", "y", {{"a", {0, 1, 2}, {1, 2, 3}}, {"b", {0, 1, 2}, {3, 2, 1}}}};
    Image image = render_line_plot(plot);
    EXPECT_EQ(image.width, plot.width);
    EXPECT_GT(count_color(image, {31, 119, 180}), 200);  // first series: lines and markers
    EXPECT_GT(count_color(image, {214, 39, 40}), 200);   // second series
    // A series with a non-finite value still draws its finite points.
    LinePlot gap{"", "", "", {{"c", {0, 1, 2}, {1, NAN, 3}}}};
    EXPECT_GT(count_color(render_line_plot(gap), {31, 119, 180}), 50);
    LinePlot bad{"", "", "", {{"d", {0, 1}, {1}}}};
    EXPECT_THROW(render_line_plot(bad), InputError);
}

}  // namespace
}  // namespace pumeta
