// A small CPU renderer for point clouds: z-buffered round splats seen from a fixed direction,
// shaded by depth, on a white background; contact sheets of several renders; PNG output.
// For looking at data and results (pumeta's figures), not for speed: one thread, O(N r^2).
#pragma once

#include <ATen/core/Tensor.h>

#include <array>
#include <cstdint>
#include <string>
#include <vector>

namespace pumeta {

/// An 8-bit RGB image, rows from the top, 3 bytes per pixel.
struct Image {
    int width = 0;
    int height = 0;
    std::vector<uint8_t> rgb;

    Image() = default;
    /// width x height filled with `fill`.
    Image(int width, int height, std::array<uint8_t, 3> fill = {255, 255, 255});

    uint8_t* pixel(int x, int y) { return rgb.data() + 3 * (static_cast<size_t>(y) * width + x); }
    const uint8_t* pixel(int x, int y) const {
        return rgb.data() + 3 * (static_cast<size_t>(y) * width + x);
    }
};

/// The sphere a render is fitted to: the whole sphere is visible, within the margin.
struct RenderFrame {
    std::array<double, 3> center{0, 0, 0};
    /// 0 = fit the sphere to the cloud being rendered (see fit_frame).
    double radius = 0;
};

struct RenderOptions {
    int width = 512;
    int height = 512;
    /// Camera direction in degrees above the horizontal plane, in [-90, 90].
    double elevation = 20;
    /// Camera direction in degrees about the up axis, from the front axis towards the right
    /// axis. With up = y the front axis is +z and the right axis +x, with up = z they are +x
    /// and +y (the axes following the up axis in x-y-z order): azimuth 0 and elevation 0 look
    /// along -front, with right to the right of the image.
    double azimuth = 45;
    /// 0 = x, 1 = y (ShapeNet-style meshes), 2 = z.
    int up_axis = 1;
    /// Perspective with this vertical field of view (degrees, in (0, 170)); orthographic if
    /// false.
    bool perspective = false;
    double field_of_view = 40;
    /// Splat radius in pixels, >= 0.5; 0 = automatic: 0.4 min(width, height) / sqrt(N),
    /// within [1, 6].
    double point_radius = 0;
    /// Fraction of the half image size left free around the frame sphere, in [0, 1).
    double margin = 0.05;
    /// Farthest points are darkened by this fraction, nearest not at all; in [0, 1].
    double depth_shading = 0.45;
    /// Splats are shaded like small spheres lit from the camera, darkening their rims by this
    /// fraction; 0 = flat discs. In [0, 1].
    double splat_shading = 0.25;
    /// Colour of points without per-point colours, RGB in [0, 1].
    std::array<float, 3> color{0.2f, 0.42f, 0.82f};
    std::array<uint8_t, 3> background{255, 255, 255};
    /// What to fit the view to (default: the cloud itself). Render several clouds of one
    /// object with the same frame so that they line up.
    RenderFrame frame;
};

/// The bounding sphere used by default: the centre of the bounding box and the largest
/// distance from it (1 when that is 0). Non-finite points are ignored. points: float32 [N,3].
RenderFrame fit_frame(const at::Tensor& points);

/// Renders points float32 [N,3] (N may be 0; non-finite points are skipped). colors: float32
/// [N,3] in [0, 1] (clamped) or undefined for options.color. Nearer splats hide farther ones;
/// on equal depth the earlier point wins, so the output is deterministic.
/// InputError for bad shapes or options.
Image render_image(const at::Tensor& points, const RenderOptions& options = {},
                   const at::Tensor& colors = {});

/// render_image written to a PNG file.
void render_points(const at::Tensor& points, const std::string& png_path,
                   const RenderOptions& options = {}, const at::Tensor& colors = {});

/// A contact sheet: images in rows of `columns` cells (each as large as the largest image,
/// images centred), separated by `gap` pixels of white; with labels (one per image, may be
/// shorter or contain empty strings) a strip of text under each cell. Text is drawn with
/// stb_easy_font (printable ASCII), scaled up for large cells.
Image render_grid(const std::vector<Image>& images, int columns,
                  const std::vector<std::string>& labels = {}, int gap = 4);

/// Draws printable-ASCII `text` with stb_easy_font, `scale` pixels per font unit, centred on
/// x = centre_x with its top at y = top, clipped to columns [clip_x0, clip_x1) (-1: the width).
void draw_text(Image& image, const std::string& text, int centre_x, int top, int scale,
               std::array<uint8_t, 3> color = {30, 30, 30}, int clip_x0 = 0, int clip_x1 = -1);

/// Width in pixels of `text` drawn by draw_text at `scale`.
int text_width(const std::string& text, int scale);

/// Writes an 8-bit RGB PNG, atomically (temporary file, then rename). InputError when the
/// image is malformed or the file cannot be written.
void write_png(const std::string& path, const Image& image);

/// Colours for scalar values: float32 [N] -> float32 [N,3] in [0, 1], along a viridis-like
/// map (dark blue-violet through green to yellow, monotone in luminance) with `lo` -> dark and
/// `hi` -> yellow; values outside are clamped, NaN becomes grey.
at::Tensor colormap(const at::Tensor& values, double lo, double hi);

/// colormap over the finite values' own range (all dark when that range is empty).
at::Tensor colormap(const at::Tensor& values);

/// The one colouring of errors shared by every picture that compares clouds (`pumeta render
/// --error-to`, the report's figures): distances float32 [N_i] per cloud -> colours
/// float32 [N_i,3], on one scale from 0 (dark) to the 95th percentile of all distances
/// together (yellow), so that clouds side by side compare and a few outliers do not wash out
/// the rest.
std::vector<at::Tensor> error_colors(const std::vector<at::Tensor>& distances);
/// The same on a scale from 0 to `hi` already computed (error_scale).
std::vector<at::Tensor> error_colors(const std::vector<at::Tensor>& distances, double hi);

/// The top of error_colors' scale: the 95th percentile of all distances together (0 for none).
double error_scale(const std::vector<at::Tensor>& distances);

/// `image` with a strip below it: a colour bar of colormap from `lo` (left) to `hi` (right),
/// its two ends labelled with their values and `unit` (may be empty), and a caption line under
/// it (what the colours measure). The image keeps its width (at least 160 pixels wide);
/// InputError unless lo < hi.
Image with_color_bar(const Image& image, double lo, double hi, const std::string& unit,
                     const std::string& caption);

}  // namespace pumeta
