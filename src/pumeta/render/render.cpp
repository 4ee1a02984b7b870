#include "pumeta/render/render.h"

#include <ATen/ATen.h>
#include <fmt/format.h>
#include <stb/stb_image_write.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>

#include "pumeta/core/error.h"
#include "pumeta/core/tensor_checks.h"
#include "pumeta/geometry/io/file.h"

// stb_easy_font is all static functions; this file uses some of them.
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wunused-function"
#include <stb/stb_easy_font.h>
#pragma GCC diagnostic pop

namespace pumeta {

namespace {

using Vec = std::array<double, 3>;

double dot(const Vec& a, const Vec& b) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }

Vec cross(const Vec& a, const Vec& b) {
    return {a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]};
}

void check_options(const RenderOptions& o) {
    const char* what = "render options";
    if (o.width < 1 || o.height < 1 || o.width > 16384 || o.height > 16384)
        throw_input_error(what, "image size {}x{} outside 1..16384", o.width, o.height);
    if (!(o.elevation >= -90 && o.elevation <= 90))
        throw_input_error(what, "elevation {} outside [-90, 90]", o.elevation);
    if (!std::isfinite(o.azimuth)) throw_input_error(what, "azimuth must be finite");
    if (o.up_axis < 0 || o.up_axis > 2)
        throw_input_error(what, "up axis {} is not 0 (x), 1 (y) or 2 (z)", o.up_axis);
    if (o.perspective && !(o.field_of_view > 0 && o.field_of_view < 170))
        throw_input_error(what, "field of view {} outside (0, 170)", o.field_of_view);
    if (!(o.point_radius == 0 || (o.point_radius >= 0.5 && o.point_radius <= 1000)))
        throw_input_error(what, "point radius {} is neither 0 (automatic) nor in [0.5, 1000]",
                          o.point_radius);
    if (!(o.margin >= 0 && o.margin < 1))
        throw_input_error(what, "margin {} outside [0, 1)", o.margin);
    if (!(o.depth_shading >= 0 && o.depth_shading <= 1) ||
        !(o.splat_shading >= 0 && o.splat_shading <= 1))
        throw_input_error(what, "shading fractions must be in [0, 1]");
    if (!(o.frame.radius >= 0 && std::isfinite(o.frame.radius)))
        throw_input_error(what, "frame radius {} must be finite and >= 0", o.frame.radius);
}

/// Orthographic or perspective projection of the frame sphere into the image.
class Camera {
  public:
    Camera(const RenderOptions& options, const RenderFrame& frame)
        : center_(frame.center), radius_(frame.radius), perspective_(options.perspective) {
        // (front, right, up) = the axes (up + 1, up + 2, up) mod 3, a right-handed triple.
        Vec up{0, 0, 0}, front{0, 0, 0}, right{0, 0, 0};
        up[options.up_axis] = 1;
        front[(options.up_axis + 1) % 3] = 1;
        right[(options.up_axis + 2) % 3] = 1;
        double e = options.elevation * M_PI / 180, a = options.azimuth * M_PI / 180;
        // Towards the camera from the centre; forward is its opposite.
        for (int k = 0; k < 3; ++k)
            forward_[k] = -(std::cos(e) * (std::cos(a) * front[k] + std::sin(a) * right[k]) +
                            std::sin(e) * up[k]);
        // cross(forward, up) normalised, written so that it stays defined at elevation +-90.
        for (int k = 0; k < 3; ++k) right_[k] = std::cos(a) * right[k] - std::sin(a) * front[k];
        up_ = cross(right_, forward_);
        double half = std::min(options.width, options.height) / 2.0 * (1 - options.margin);
        cx_ = options.width / 2.0;
        cy_ = options.height / 2.0;
        if (perspective_) {
            // The sphere exactly fills the field of view from this distance.
            double half_angle = options.field_of_view * M_PI / 360;
            distance_ = radius_ / std::sin(half_angle);
            scale_ = half / std::tan(half_angle);
        } else {
            scale_ = half / radius_;
        }
    }

    /// Image position of p and its depth along the view direction (relative to the frame
    /// centre; larger = farther), plus the world size of one pixel there.
    void project(const float* p, double& x, double& y, double& depth, double& pixel_size) const {
        Vec d{p[0] - center_[0], p[1] - center_[1], p[2] - center_[2]};
        double u = dot(d, right_), v = dot(d, up_);
        depth = dot(d, forward_);
        double factor = scale_;
        if (perspective_) factor = scale_ / (distance_ + depth);
        x = cx_ + u * factor;
        y = cy_ - v * factor;
        pixel_size = 1 / factor;
    }

    /// 0 for the nearest point of the frame sphere, 1 for the farthest.
    double depth_fraction(double depth) const {
        return std::clamp((depth + radius_) / (2 * radius_), 0.0, 1.0);
    }

  private:
    Vec center_;
    double radius_;
    bool perspective_;
    Vec forward_{}, right_{}, up_{};
    double cx_ = 0, cy_ = 0, scale_ = 1, distance_ = 0;
};

// Viridis sampled at 10 points (matplotlib's map, CC0); linear in between.
constexpr std::array<std::array<float, 4>, 10> kViridis{{
    {0.0f, 0.267f, 0.005f, 0.329f},
    {32 / 255.0f, 0.282f, 0.141f, 0.458f},
    {64 / 255.0f, 0.254f, 0.265f, 0.530f},
    {96 / 255.0f, 0.207f, 0.372f, 0.553f},
    {128 / 255.0f, 0.164f, 0.471f, 0.558f},
    {160 / 255.0f, 0.128f, 0.567f, 0.551f},
    {192 / 255.0f, 0.135f, 0.659f, 0.518f},
    {224 / 255.0f, 0.267f, 0.749f, 0.441f},
    {240 / 255.0f, 0.565f, 0.843f, 0.262f},
    {1.0f, 0.993f, 0.906f, 0.144f},
}};

void viridis(double t, float* rgb) {
    size_t k = 1;
    while (k + 1 < kViridis.size() && t > kViridis[k][0]) ++k;
    const auto &a = kViridis[k - 1], &b = kViridis[k];
    double w = std::clamp((t - a[0]) / (b[0] - a[0]), 0.0, 1.0);
    for (int c = 0; c < 3; ++c) rgb[c] = static_cast<float>(a[c + 1] + w * (b[c + 1] - a[c + 1]));
}

}  // namespace

namespace {

std::vector<char> font_chars(const std::string& text) {
    std::vector<char> chars;
    for (char c : text) chars.push_back(c >= 32 && c < 127 ? c : '?');
    chars.push_back('\0');
    return chars;
}

}  // namespace

int text_width(const std::string& text, int scale) {
    std::vector<char> chars = font_chars(text);
    return stb_easy_font_width(chars.data()) * scale;
}

void draw_text(Image& image, const std::string& text, int centre_x, int top, int scale,
               std::array<uint8_t, 3> color, int clip_x0, int clip_x1) {
    if (clip_x1 < 0 || clip_x1 > image.width) clip_x1 = image.width;
    clip_x0 = std::max(clip_x0, 0);
    std::vector<char> chars = font_chars(text);
    std::vector<char> vertices(300 * chars.size() + 64);
    int quads = stb_easy_font_print(0, 0, chars.data(), nullptr, vertices.data(),
                                    static_cast<int>(vertices.size()));
    int left = centre_x - stb_easy_font_width(chars.data()) * scale / 2;
    for (int q = 0; q < quads; ++q) {
        // Each quad is 4 vertices of 16 bytes (x, y, z floats, RGBA), an axis-aligned rectangle.
        const char* quad = vertices.data() + 64 * q;
        float x0 = std::numeric_limits<float>::max(), y0 = x0, x1 = -x0, y1 = -x0;
        for (int v = 0; v < 4; ++v) {
            float x, y;
            std::memcpy(&x, quad + 16 * v, sizeof(float));
            std::memcpy(&y, quad + 16 * v + 4, sizeof(float));
            x0 = std::min(x0, x), x1 = std::max(x1, x), y0 = std::min(y0, y), y1 = std::max(y1, y);
        }
        int px0 = std::max(left + static_cast<int>(std::lround(x0 * scale)), clip_x0);
        int px1 = std::min(left + static_cast<int>(std::lround(x1 * scale)), clip_x1);
        int py0 = std::max(top + static_cast<int>(std::lround(y0 * scale)), 0);
        int py1 = std::min(top + static_cast<int>(std::lround(y1 * scale)), image.height);
        for (int y = py0; y < py1; ++y)
            for (int x = px0; x < px1; ++x)
                std::copy(color.begin(), color.end(), image.pixel(x, y));
    }
}

Image::Image(int width, int height, std::array<uint8_t, 3> fill) : width(width), height(height) {
    if (width < 0 || height < 0) throw_input_error("Image", "negative size {}x{}", width, height);
    rgb.resize(static_cast<size_t>(width) * height * 3);
    for (size_t i = 0; i < rgb.size(); i += 3) std::copy(fill.begin(), fill.end(), rgb.begin() + i);
}

RenderFrame fit_frame(const at::Tensor& points) {
    check_points(points, "fit_frame");
    at::Tensor p = points.cpu().contiguous();
    const float* data = p.data_ptr<float>();
    int64_t n = p.size(0);
    Vec lo{std::numeric_limits<double>::infinity(), std::numeric_limits<double>::infinity(),
           std::numeric_limits<double>::infinity()};
    Vec hi{-lo[0], -lo[1], -lo[2]};
    auto finite = [&](int64_t i) {
        return std::isfinite(data[3 * i]) && std::isfinite(data[3 * i + 1]) &&
               std::isfinite(data[3 * i + 2]);
    };
    bool any = false;
    for (int64_t i = 0; i < n; ++i) {
        if (!finite(i)) continue;
        any = true;
        for (int k = 0; k < 3; ++k) {
            lo[k] = std::min(lo[k], static_cast<double>(data[3 * i + k]));
            hi[k] = std::max(hi[k], static_cast<double>(data[3 * i + k]));
        }
    }
    RenderFrame frame;
    if (!any) {
        frame.radius = 1;
        return frame;
    }
    for (int k = 0; k < 3; ++k) frame.center[k] = (lo[k] + hi[k]) / 2;
    double squared = 0;
    for (int64_t i = 0; i < n; ++i) {
        if (!finite(i)) continue;
        double s = 0;
        for (int k = 0; k < 3; ++k) s += std::pow(data[3 * i + k] - frame.center[k], 2);
        squared = std::max(squared, s);
    }
    frame.radius = squared > 0 ? std::sqrt(squared) : 1;
    return frame;
}

Image render_image(const at::Tensor& points, const RenderOptions& options,
                   const at::Tensor& colors) {
    check_points(points, "render points");
    check_options(options);
    int64_t n = points.size(0);
    at::Tensor p = points.cpu().contiguous(), c;
    if (colors.defined()) {
        check_points(colors, "render colors");
        if (colors.size(0) != n)
            throw_input_error("render colors", "{} colours for {} points", colors.size(0), n);
        c = colors.cpu().contiguous();
    }
    RenderFrame frame = options.frame.radius > 0 ? options.frame : fit_frame(p);
    Camera camera(options, frame);
    double radius = options.point_radius;
    if (radius == 0)
        radius = std::clamp(0.4 * std::min(options.width, options.height) /
                                std::sqrt(static_cast<double>(std::max<int64_t>(n, 1))),
                            1.0, 6.0);

    Image image(options.width, options.height, options.background);
    std::vector<double> depth_buffer(static_cast<size_t>(options.width) * options.height,
                                     std::numeric_limits<double>::infinity());
    const float* pd = p.data_ptr<float>();
    const float* cd = c.defined() ? c.data_ptr<float>() : nullptr;
    int reach = static_cast<int>(std::ceil(radius));
    for (int64_t i = 0; i < n; ++i) {
        const float* point = pd + 3 * i;
        if (!std::isfinite(point[0]) || !std::isfinite(point[1]) || !std::isfinite(point[2]))
            continue;
        double sx, sy, depth, pixel_size;
        camera.project(point, sx, sy, depth, pixel_size);
        if (!(std::abs(sx) < 1e7 && std::abs(sy) < 1e7)) continue;
        const float* base = cd ? cd + 3 * i : options.color.data();
        double shade = 1 - options.depth_shading * camera.depth_fraction(depth);
        int hx = static_cast<int>(std::floor(sx)), hy = static_cast<int>(std::floor(sy));
        for (int y = std::max(hy - reach, 0); y <= std::min(hy + reach, options.height - 1); ++y) {
            for (int x = std::max(hx - reach, 0); x <= std::min(hx + reach, options.width - 1);
                 ++x) {
                double dx = x + 0.5 - sx, dy = y + 0.5 - sy;
                double r2 = (dx * dx + dy * dy) / (radius * radius);
                // The pixel holding the point is always drawn, however small the radius.
                bool home = x == hx && y == hy;
                if (r2 > 1 && !home) continue;
                // A sphere impostor: the splat's surface bulges towards the camera, so that
                // overlapping splats intersect like balls.
                double bulge = std::sqrt(std::max(0.0, 1 - r2));
                double z = depth - bulge * radius * pixel_size;
                double& stored = depth_buffer[static_cast<size_t>(y) * options.width + x];
                if (!(z < stored)) continue;
                stored = z;
                double light = shade * (1 - options.splat_shading * (1 - bulge));
                uint8_t* out = image.pixel(x, y);
                for (int k = 0; k < 3; ++k)
                    out[k] = static_cast<uint8_t>(
                        std::lround(255 * std::clamp(base[k] * light, 0.0, 1.0)));
            }
        }
    }
    return image;
}

void render_points(const at::Tensor& points, const std::string& png_path,
                   const RenderOptions& options, const at::Tensor& colors) {
    write_png(png_path, render_image(points, options, colors));
}

Image render_grid(const std::vector<Image>& images, int columns,
                  const std::vector<std::string>& labels, int gap) {
    if (images.empty()) throw_input_error("render_grid", "no images");
    if (columns < 1) throw_input_error("render_grid", "columns must be >= 1, got {}", columns);
    if (gap < 0) throw_input_error("render_grid", "gap must be >= 0, got {}", gap);
    int cell_width = 0, cell_height = 0;
    for (const Image& image : images) {
        if (image.rgb.size() != static_cast<size_t>(image.width) * image.height * 3)
            throw_input_error("render_grid", "malformed {}x{} image", image.width, image.height);
        cell_width = std::max(cell_width, image.width);
        cell_height = std::max(cell_height, image.height);
    }
    bool labelled = std::any_of(labels.begin(), labels.end(),
                                [](const std::string& label) { return !label.empty(); });
    // stb_easy_font's capitals are 7 units high, descenders reach 10.
    int text_scale = std::max(1, cell_width / 256);
    int strip = labelled ? 13 * text_scale : 0;
    int count = static_cast<int>(images.size());
    int used_columns = std::min(columns, count);
    int rows = (count + columns - 1) / columns;
    Image sheet(used_columns * cell_width + (used_columns + 1) * gap,
                rows * (cell_height + strip) + (rows + 1) * gap);
    for (int i = 0; i < count; ++i) {
        const Image& image = images[i];
        int x0 = gap + (i % columns) * (cell_width + gap);
        int y0 = gap + (i / columns) * (cell_height + strip + gap);
        int ox = x0 + (cell_width - image.width) / 2, oy = y0 + (cell_height - image.height) / 2;
        for (int y = 0; y < image.height; ++y)
            std::copy_n(image.pixel(0, y), 3 * image.width, sheet.pixel(ox, oy + y));
        if (i < static_cast<int>(labels.size()) && !labels[i].empty())
            draw_text(sheet, labels[i], x0 + cell_width / 2, y0 + cell_height + 2 * text_scale,
                      text_scale, {30, 30, 30}, x0, x0 + cell_width);
    }
    return sheet;
}

void write_png(const std::string& path, const Image& image) {
    if (image.width < 1 || image.height < 1 ||
        image.rgb.size() != static_cast<size_t>(image.width) * image.height * 3)
        throw_input_error(path, "cannot write a malformed {}x{} image of {} bytes", image.width,
                          image.height, image.rgb.size());
    std::string bytes;
    auto append = [](void* context, void* data, int size) {
        static_cast<std::string*>(context)->append(static_cast<const char*>(data), size);
    };
    if (!stbi_write_png_to_func(append, &bytes, image.width, image.height, 3, image.rgb.data(),
                                3 * image.width))
        throw_input_error(path, "PNG encoding failed");
    io::write_atomically(path, bytes);
}

at::Tensor colormap(const at::Tensor& values, double lo, double hi) {
    if (!values.defined() || values.dim() != 1 || !values.is_floating_point())
        throw_input_error("colormap", "expected floating-point values of shape [N], found {}",
                          shape_string(values));
    at::Tensor v = values.to(at::kDouble).cpu().contiguous();
    const double* data = v.data_ptr<double>();
    int64_t n = v.size(0);
    at::Tensor out = at::empty({n, 3}, at::kFloat);
    float* rgb = out.data_ptr<float>();
    for (int64_t i = 0; i < n; ++i) {
        if (std::isnan(data[i])) {
            std::fill_n(rgb + 3 * i, 3, 0.6f);
            continue;
        }
        double t = hi > lo ? (data[i] - lo) / (hi - lo) : 0;
        viridis(std::clamp(t, 0.0, 1.0), rgb + 3 * i);
    }
    return out;
}

at::Tensor colormap(const at::Tensor& values) {
    if (!values.defined() || values.dim() != 1 || !values.is_floating_point())
        throw_input_error("colormap", "expected floating-point values of shape [N], found {}",
                          shape_string(values));
    at::Tensor v = values.to(at::kDouble);
    at::Tensor finite = v.masked_select(at::isfinite(v));
    if (finite.numel() == 0) return colormap(values, 0, 0);
    return colormap(values, finite.min().item<double>(), finite.max().item<double>());
}

double error_scale(const std::vector<at::Tensor>& distances) {
    if (distances.empty()) return 0;
    const at::Tensor all = at::cat(distances).to(at::kDouble);
    return all.numel() > 0 ? at::quantile(all, 0.95).item<double>() : 0.0;
}

std::vector<at::Tensor> error_colors(const std::vector<at::Tensor>& distances) {
    return error_colors(distances, error_scale(distances));
}

std::vector<at::Tensor> error_colors(const std::vector<at::Tensor>& distances, double hi) {
    std::vector<at::Tensor> colors;
    for (const at::Tensor& d : distances) colors.push_back(colormap(d, 0, hi));
    return colors;
}

Image with_color_bar(const Image& image, double lo, double hi, const std::string& unit,
                     const std::string& caption) {
    if (!(lo < hi)) throw_input_error("color bar", "needs lo < hi, found {} and {}", lo, hi);
    const int width = std::max(image.width, 160);
    // Font pixels per unit: 2 on large images where the caption then fits.
    const int scale = width >= 480 && text_width(caption, 2) <= width - 16 ? 2 : 1;
    const int line = 12 * scale, margin = 8 * scale, bar_height = 10 * scale;
    const int bar_left = margin, bar_right = width - margin;
    Image out(width, image.height + bar_height + 2 * line + 3 * margin, {255, 255, 255});
    for (int y = 0; y < image.height; ++y)
        std::memcpy(out.pixel((width - image.width) / 2, y), image.pixel(0, y), 3 * image.width);
    // The bar: one column per value from lo to hi.
    const at::Tensor values = at::linspace(lo, hi, bar_right - bar_left, at::kFloat);
    const at::Tensor colors = colormap(values, lo, hi);
    const float* rgb = colors.data_ptr<float>();
    const int top = image.height + margin;
    for (int x = bar_left; x < bar_right; ++x)
        for (int y = top; y < top + bar_height; ++y)
            for (int c = 0; c < 3; ++c)
                out.pixel(x, y)[c] =
                    static_cast<uint8_t>(std::lround(255 * rgb[3 * (x - bar_left) + c]));
    // The ends' values, then the caption.
    const std::string suffix = unit.empty() ? "" : " " + unit;
    const std::string low = fmt::format("{:.3g}{}", lo, suffix);
    const std::string high = fmt::format(">= {:.3g}{}", hi, suffix);
    const int labels = top + bar_height + margin / 2;
    draw_text(out, low, bar_left + text_width(low, scale) / 2, labels, scale);
    draw_text(out, high, bar_right - text_width(high, scale) / 2, labels, scale);
    draw_text(out, caption, width / 2, labels + line, scale);
    return out;
}

}  // namespace pumeta
