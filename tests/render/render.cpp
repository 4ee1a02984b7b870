#include "pumeta/render/render.h"

#include <ATen/ATen.h>
#include <gtest/gtest.h>
#include <stb/stb_image.h>

#include <cmath>
#include <filesystem>

#include "pumeta/core/error.h"
#include "pumeta/geometry/sampling.h"
#include "support/test_util.h"

namespace pumeta {

namespace {

bool is_background(const Image& image, int x, int y) {
    const uint8_t* p = image.pixel(x, y);
    return p[0] == 255 && p[1] == 255 && p[2] == 255;
}

/// Mean position (pixel indices) of the non-background pixels; count in `drawn`.
std::array<double, 2> drawn_centroid(const Image& image, int& drawn) {
    double sx = 0, sy = 0;
    drawn = 0;
    for (int y = 0; y < image.height; ++y)
        for (int x = 0; x < image.width; ++x)
            if (!is_background(image, x, y)) {
                sx += x;
                sy += y;
                ++drawn;
            }
    return {sx / std::max(drawn, 1), sy / std::max(drawn, 1)};
}

at::Tensor points_of(std::initializer_list<std::array<float, 3>> list) {
    at::Tensor points = at::empty({static_cast<int64_t>(list.size()), 3}, at::kFloat);
    int64_t i = 0;
    for (const auto& p : list) {
        for (int k = 0; k < 3; ++k) points[i][k] = p[k];
        ++i;
    }
    return points;
}

/// Flat colours, front view along -z with y up, x to the right.
RenderOptions flat_front_view() {
    RenderOptions options;
    options.elevation = 0;
    options.azimuth = 0;
    options.depth_shading = 0;
    options.splat_shading = 0;
    return options;
}

}  // namespace

TEST(Render, ImageHasTheRequestedSizeAndAWhiteBackground) {
    RenderOptions options;
    options.width = 320;
    options.height = 200;
    Image image = render_image(uniform_random_points(500, 1), options);
    EXPECT_EQ(image.width, 320);
    EXPECT_EQ(image.height, 200);
    ASSERT_EQ(image.rgb.size(), 320u * 200 * 3);
    for (auto [x, y] : {std::pair{0, 0}, {319, 0}, {0, 199}, {319, 199}})
        EXPECT_TRUE(is_background(image, x, y));
    int drawn = 0;
    drawn_centroid(image, drawn);
    EXPECT_GT(drawn, 2000);
    // An empty cloud is all background.
    Image empty = render_image(at::zeros({0, 3}), options);
    drawn_centroid(empty, drawn);
    EXPECT_EQ(drawn, 0);
}

TEST(Render, SinglePointLandsInTheImageCentre) {
    for (auto [w, h] : {std::pair{64, 64}, {101, 77}}) {
        RenderOptions options;
        options.width = w;
        options.height = h;
        options.point_radius = 3;
        int drawn = 0;
        auto [cx, cy] = drawn_centroid(render_image(points_of({{0.3f, -2, 5}}), options), drawn);
        EXPECT_GT(drawn, 20);
        // Pixel i covers [i, i + 1): the image centre w/2 is at index w/2 - 0.5.
        EXPECT_NEAR(cx, w / 2.0 - 0.5, 1e-9);
        EXPECT_NEAR(cy, h / 2.0 - 0.5, 1e-9);
    }
}

TEST(Render, NearerPointsHideFartherOnesWhateverTheOrder) {
    RenderOptions options = flat_front_view();
    options.frame = {{0, 0, 0}, 2};  // both points project to the centre
    at::Tensor colors = points_of({{1, 0, 0}, {0, 1, 0}});
    at::Tensor near_first = points_of({{0, 0, 1}, {0, 0, -1}});
    at::Tensor far_first = points_of({{0, 0, -1}, {0, 0, 1}});
    at::Tensor swapped = points_of({{0, 1, 0}, {1, 0, 0}});
    for (const Image& image :
         {render_image(near_first, options, colors), render_image(far_first, options, swapped)}) {
        const uint8_t* centre = image.pixel(image.width / 2, image.height / 2);
        EXPECT_EQ(centre[0], 255);
        EXPECT_EQ(centre[1], 0);
        EXPECT_EQ(centre[2], 0);
    }
    // Seen from behind (azimuth 180) the other point is in front.
    options.azimuth = 180;
    const uint8_t* centre = render_image(near_first, options, colors).pixel(256, 256);
    EXPECT_EQ(centre[1], 255);
}

TEST(Render, AxesFollowTheDocumentedConventions) {
    RenderOptions options = flat_front_view();
    options.frame = {{0, 0, 0}, 1};
    auto centroid = [&](std::array<float, 3> p) {
        int drawn = 0;
        return drawn_centroid(render_image(points_of({p}), options), drawn);
    };
    // y up, front +z, right +x.
    EXPECT_GT(centroid({0.5f, 0, 0})[0], 300);
    EXPECT_LT(centroid({0, 0.5f, 0})[1], 200);
    // Azimuth 90 looks from +x: right is -z.
    options.azimuth = 90;
    EXPECT_GT(centroid({0, 0, -0.5f})[0], 300);
    // z up: front +x, right +y.
    options.azimuth = 0;
    options.up_axis = 2;
    EXPECT_LT(centroid({0, 0, 0.5f})[1], 200);
    EXPECT_GT(centroid({0, 0.5f, 0})[0], 300);
    // Looking straight down stays well defined, with +z (the front for y up) at the bottom.
    options.up_axis = 1;
    options.elevation = 90;
    EXPECT_GT(centroid({0, 0, 0.5f})[1], 300);
    EXPECT_NEAR(centroid({0, 0.5f, 0})[1], 255.5, 1e-9);
}

TEST(Render, DepthShadingMakesNearerPointsBrighter) {
    RenderOptions options;
    options.elevation = 0;
    options.azimuth = 0;
    options.splat_shading = 0;
    Image image = render_image(points_of({{-0.5f, 0, 0.5f}, {0.5f, 0, -0.5f}}), options);
    int drawn = 0;
    auto [cx, cy] = drawn_centroid(image, drawn);
    int y = static_cast<int>(cy);
    int near = 0, far = 0;
    for (int x = 0; x < image.width; ++x) {
        if (is_background(image, x, y)) continue;
        int brightness = image.pixel(x, y)[0] + image.pixel(x, y)[1] + image.pixel(x, y)[2];
        (x < cx ? near : far) = brightness;
    }
    EXPECT_GT(near, far + 50);
}

TEST(Render, PerspectiveShrinksFartherObjects) {
    at::Tensor points = points_of({{-0.3f, 0.5f, 0.6f},
                                   {0.3f, 0.5f, 0.6f},  // near pair
                                   {-0.3f, -0.5f, -0.6f},
                                   {0.3f, -0.5f, -0.6f}});
    auto spans = [&](bool perspective) {
        RenderOptions options = flat_front_view();
        options.perspective = perspective;
        options.point_radius = 1;
        Image image = render_image(points, options);
        std::array<int, 2> span{0, 0};  // upper (near) and lower (far) pair
        for (int half = 0; half < 2; ++half) {
            int lo = image.width, hi = -1;
            for (int y = half * image.height / 2; y < (half + 1) * image.height / 2; ++y)
                for (int x = 0; x < image.width; ++x)
                    if (!is_background(image, x, y)) lo = std::min(lo, x), hi = std::max(hi, x);
            span[half] = hi - lo;
        }
        return span;
    };
    auto ortho = spans(false), persp = spans(true);
    EXPECT_NEAR(ortho[0], ortho[1], 1);
    EXPECT_GT(persp[0], persp[1] * 1.3);
}

TEST(Render, AutoFitFillsTheImageInvariantToSimilarity) {
    at::Tensor sphere = uniform_random_points(4000, 2);
    sphere = sphere / sphere.norm(2, 1, true);
    RenderOptions options;
    options.margin = 0.1;
    options.point_radius = 2;
    Image image = render_image(sphere, options);
    double reach = 0;
    for (int y = 0; y < image.height; ++y)
        for (int x = 0; x < image.width; ++x)
            if (!is_background(image, x, y))
                reach = std::max(reach, std::hypot(x + 0.5 - 256, y + 0.5 - 256));
    // The unit sphere's outline is at 0.9 * 256 pixels, splats add their radius.
    EXPECT_NEAR(reach, 0.9 * 256 + 2, 3);
    Image moved = render_image(sphere * 3.5 + at::tensor({10.f, -4.f, 2.f}), options);
    int differing = 0;
    for (size_t i = 0; i < image.rgb.size(); i += 3)
        differing += !std::equal(&image.rgb[i], &image.rgb[i] + 3, &moved.rgb[i]);
    EXPECT_LT(differing, 0.002 * image.width * image.height);
}

TEST(Render, PerPointColoursAreDrawnAndOutputIsDeterministic) {
    RenderOptions options = flat_front_view();
    at::Tensor colors = points_of({{0.2f, 0.4f, 0.6f}});
    Image image = render_image(points_of({{0, 0, 0}}), options, colors);
    const uint8_t* centre = image.pixel(256, 256);
    EXPECT_EQ(centre[0], 51);
    EXPECT_EQ(centre[1], 102);
    EXPECT_EQ(centre[2], 153);
    at::Tensor cloud = uniform_random_points(3000, 9);
    Image a = render_image(cloud, RenderOptions{}), b = render_image(cloud, RenderOptions{});
    EXPECT_EQ(a.rgb, b.rgb);
}

TEST(Render, PngFilesRoundTripThroughStbImage) {
    test::TempDir dir;
    std::string path = dir.file("cloud.png");
    RenderOptions options;
    options.width = 97;
    options.height = 61;
    at::Tensor cloud = uniform_random_points(300, 4);
    render_points(cloud, path, options, colormap(cloud.select(1, 0)));
    std::string bytes = test::read_file(path);
    ASSERT_GE(bytes.size(), 8u);
    EXPECT_EQ(bytes.substr(0, 8), std::string("\x89PNG\r\n\x1a\n", 8));
    int w = 0, h = 0, channels = 0;
    unsigned char* decoded = stbi_load(path.c_str(), &w, &h, &channels, 3);
    ASSERT_NE(decoded, nullptr);
    Image expected = render_image(cloud, options, colormap(cloud.select(1, 0)));
    EXPECT_EQ(w, 97);
    EXPECT_EQ(h, 61);
    EXPECT_EQ(channels, 3);
    EXPECT_TRUE(std::equal(expected.rgb.begin(), expected.rgb.end(), decoded));
    stbi_image_free(decoded);
    // Only the PNG is left: the temporary file was renamed.
    EXPECT_EQ(std::distance(std::filesystem::directory_iterator(dir.path()), {}), 1);
    EXPECT_THROW(write_png(dir.file("missing/dir/x.png"), expected), InputError);
    EXPECT_THROW(write_png(path, Image{}), InputError);
}

TEST(Render, GridPlacesImagesInRowsWithLabels) {
    std::vector<Image> images{Image(20, 10, {255, 0, 0}), Image(20, 10, {0, 255, 0}),
                              Image(10, 6, {0, 0, 255})};
    Image sheet = render_grid(images, 2, {}, 3);
    EXPECT_EQ(sheet.width, 2 * 20 + 3 * 3);
    EXPECT_EQ(sheet.height, 2 * 10 + 3 * 3);
    EXPECT_EQ(sheet.pixel(3 + 10, 3 + 5)[0], 255);             // first cell
    EXPECT_EQ(sheet.pixel(3 + 20 + 3 + 10, 3 + 5)[1], 255);    // second cell
    EXPECT_EQ(sheet.pixel(3 + 10, 3 + 10 + 3 + 5)[2], 255);    // third, centred
    EXPECT_TRUE(is_background(sheet, 3 + 1, 3 + 10 + 3 + 1));  // outside the smaller image
    EXPECT_TRUE(is_background(sheet, 3 + 20 + 3 + 10, 3 + 10 + 3 + 5));  // empty cell

    std::vector<Image> big{Image(300, 40, {200, 200, 200}), Image(300, 40, {200, 200, 200})};
    Image labelled = render_grid(big, 2, {"PU-GCN 4x", ""}, 0);
    EXPECT_EQ(labelled.height, 40 + 13);
    auto dark_pixels = [&](int x0, int x1) {
        int dark = 0;
        for (int y = 40; y < labelled.height; ++y)
            for (int x = x0; x < x1; ++x) dark += labelled.pixel(x, y)[0] < 100;
        return dark;
    };
    EXPECT_GT(dark_pixels(0, 300), 30);
    EXPECT_EQ(dark_pixels(300, 600), 0);
    EXPECT_THROW(render_grid({}, 2), InputError);
    EXPECT_THROW(render_grid(big, 0), InputError);
}

TEST(Render, ColormapIsMonotoneInLuminanceAndClamps) {
    at::Tensor ramp = at::linspace(0, 1, 101, at::kFloat);
    at::Tensor rgb = colormap(ramp, 0, 1);
    ASSERT_EQ(rgb.sizes(), (std::vector<int64_t>{101, 3}));
    at::Tensor luminance = at::matmul(rgb, at::tensor({0.2126f, 0.7152f, 0.0722f}));
    EXPECT_TRUE((luminance.slice(0, 1) > luminance.slice(0, 0, -1)).all().item<bool>());
    EXPECT_GE(rgb.min().item<float>(), 0);
    EXPECT_LE(rgb.max().item<float>(), 1);
    // Dark violet at the low end, yellow at the high end.
    EXPECT_GT(rgb[0][2].item<float>(), rgb[0][1].item<float>());
    EXPECT_GT(rgb[100][0].item<float>(), 0.9f);
    EXPECT_LT(rgb[100][2].item<float>(), 0.3f);
    at::Tensor outside = colormap(at::tensor({-5.f, 7.f, NAN}), 0, 1);
    EXPECT_TRUE(at::equal(outside[0], rgb[0]));
    EXPECT_TRUE(at::equal(outside[1], rgb[100]));
    EXPECT_FLOAT_EQ(outside[2][0].item<float>(), outside[2][1].item<float>());
    // The automatic range is the values' own.
    EXPECT_TRUE(at::allclose(colormap(ramp * 4 + 2), rgb, 0, 1e-6));
    EXPECT_THROW(colormap(at::zeros({3, 2})), InputError);
}

TEST(Render, ErrorColoursShareOneScaleUpToThe95thPercentile) {
    // 0..99 in one cloud, 100..199 in the other: the shared 95th percentile is 189.05.
    at::Tensor low = at::arange(100, at::kFloat), high = at::arange(100, 200, at::kFloat);
    std::vector<at::Tensor> colors = error_colors({low, high});
    ASSERT_EQ(colors.size(), 2u);
    const double hi = at::quantile(at::cat({low, high}).to(at::kDouble), 0.95).item<double>();
    EXPECT_TRUE(at::equal(colors[0], colormap(low, 0, hi)));
    EXPECT_TRUE(at::equal(colors[1], colormap(high, 0, hi)));
    // The lower cloud never reaches yellow; the top 5% are clamped to it.
    EXPECT_LT(colors[0][99][0].item<float>(), colors[1][99][0].item<float>());
    EXPECT_TRUE(at::equal(colors[1][99], colors[1][95]));
    EXPECT_TRUE(error_colors({}).empty());
}

// The strip under an error picture: the image unchanged above it, the bar from the colour
// of lo on the left to that of hi on the right, dark label pixels under it.
TEST(Render, ColorBarShowsTheScaleUnderTheImage) {
    Image image(200, 100, {10, 20, 30});
    const Image out = with_color_bar(image, 0, 0.5, "", "distance to gt.xyz");
    ASSERT_EQ(out.width, 200);
    ASSERT_GT(out.height, 130);
    for (int y : {0, 99})
        for (int c = 0; c < 3; ++c) EXPECT_EQ(out.pixel(100, y)[c], image.pixel(100, y)[c]);
    // The bar's first and last columns, in the middle of its height.
    int bar_y = -1;
    for (int y = 100; y < out.height && bar_y < 0; ++y)
        if (out.pixel(out.width / 2, y)[0] != 255 || out.pixel(out.width / 2, y)[2] != 255)
            bar_y = y + 4;
    ASSERT_GE(bar_y, 100);
    const at::Tensor ends = colormap(at::tensor({0.0f, 0.5f}), 0, 0.5);
    for (int c = 0; c < 3; ++c) {
        EXPECT_NEAR(out.pixel(8, bar_y)[c], 255 * ends[0][c].item<float>(), 1.0);
        EXPECT_NEAR(out.pixel(out.width - 9, bar_y)[c], 255 * ends[1][c].item<float>(), 1.0);
    }
    // Text below the bar: some dark pixels.
    int dark = 0;
    for (int y = bar_y + 8; y < out.height; ++y)
        for (int x = 0; x < out.width; ++x) dark += out.pixel(x, y)[0] < 100;
    EXPECT_GT(dark, 50);
    EXPECT_THROW(with_color_bar(image, 1, 1, "", ""), InputError);
}

TEST(Render, RejectsBadInputs) {
    at::Tensor cloud = uniform_random_points(10, 1);
    EXPECT_THROW(render_image(at::zeros({4, 2})), InputError);
    EXPECT_THROW(render_image(cloud, {}, at::zeros({9, 3})), InputError);
    RenderOptions options;
    options.elevation = 95;
    EXPECT_THROW(render_image(cloud, options), InputError);
    options = {};
    options.width = 0;
    EXPECT_THROW(render_image(cloud, options), InputError);
    options = {};
    options.point_radius = 0.1;
    EXPECT_THROW(render_image(cloud, options), InputError);
    options = {};
    options.perspective = true;
    options.field_of_view = 180;
    EXPECT_THROW(render_image(cloud, options), InputError);
}

}  // namespace pumeta
