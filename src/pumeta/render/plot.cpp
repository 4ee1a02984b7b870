#include "pumeta/render/plot.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <limits>

#include "pumeta/core/error.h"

namespace pumeta {

namespace {

constexpr std::array<std::array<uint8_t, 3>, 6> kPalette{
    {{31, 119, 180}, {214, 39, 40}, {44, 160, 44}, {255, 127, 14}, {148, 103, 189}, {140, 86, 75}}};

void fill_rect(Image& image, int x0, int y0, int x1, int y1, std::array<uint8_t, 3> color) {
    for (int y = std::max(y0, 0); y < std::min(y1, image.height); ++y)
        for (int x = std::max(x0, 0); x < std::min(x1, image.width); ++x)
            std::copy(color.begin(), color.end(), image.pixel(x, y));
}

// A line `thickness` pixels wide, drawn as overlapping squares along its length.
void draw_line(Image& image, double x0, double y0, double x1, double y1,
               std::array<uint8_t, 3> color, int thickness) {
    int steps = static_cast<int>(std::ceil(std::max(std::abs(x1 - x0), std::abs(y1 - y0)))) + 1;
    for (int i = 0; i <= steps; ++i) {
        double t = static_cast<double>(i) / steps;
        int x = static_cast<int>(std::lround(x0 + t * (x1 - x0)));
        int y = static_cast<int>(std::lround(y0 + t * (y1 - y0)));
        fill_rect(image, x - thickness / 2, y - thickness / 2, x - thickness / 2 + thickness,
                  y - thickness / 2 + thickness, color);
    }
}

std::string tick_label(double v, double step) {
    if (v == 0) return "0";
    double magnitude = std::abs(v);
    if (magnitude >= 1e4 || magnitude < 1e-3) return fmt::format("{:.2g}", v);
    int decimals = std::max(0, static_cast<int>(std::ceil(-std::log10(step) - 1e-9)));
    return fmt::format("{:.{}f}", v, decimals);
}

}  // namespace

std::vector<double> nice_ticks(double lo, double hi, int count) {
    if (!(hi > lo)) return {lo};
    double raw = (hi - lo) / std::max(count, 1);
    double power = std::pow(10.0, std::floor(std::log10(raw)));
    double step = power;
    for (double m : {1.0, 2.0, 5.0, 10.0})
        if (m * power >= raw) {
            step = m * power;
            break;
        }
    std::vector<double> ticks;
    for (double v = std::ceil(lo / step - 1e-9) * step; v <= hi + 1e-9 * step; v += step)
        ticks.push_back(std::abs(v) < 1e-12 * step ? 0.0 : v);
    return ticks;
}

Image render_line_plot(const LinePlot& plot) {
    double x_lo = std::numeric_limits<double>::infinity(), x_hi = -x_lo, y_lo = x_lo, y_hi = -x_lo;
    for (const PlotSeries& s : plot.series) {
        if (s.x.size() != s.y.size())
            throw_input_error("line plot", "series '{}' has {} x values but {} y values", s.label,
                              s.x.size(), s.y.size());
        for (size_t i = 0; i < s.x.size(); ++i) {
            if (!std::isfinite(s.x[i]) || !std::isfinite(s.y[i])) continue;
            x_lo = std::min(x_lo, s.x[i]), x_hi = std::max(x_hi, s.x[i]);
            y_lo = std::min(y_lo, s.y[i]), y_hi = std::max(y_hi, s.y[i]);
        }
    }
    if (!std::isfinite(x_lo)) x_lo = 0, x_hi = 1, y_lo = 0, y_hi = 1;
    if (x_hi == x_lo) x_lo -= 0.5, x_hi += 0.5;
    if (y_hi == y_lo) y_lo -= 0.5 * std::max(std::abs(y_lo), 1e-12), y_hi = 2 * y_hi - y_lo;
    double pad = 0.08 * (y_hi - y_lo);
    y_lo -= pad, y_hi += pad;

    Image image(plot.width, plot.height);
    const int scale = 2, left = 90, right = 20, top = 60, bottom = 60;
    const int x0 = left, x1 = plot.width - right, y0 = top, y1 = plot.height - bottom;
    auto px = [&](double x) { return x0 + (x - x_lo) / (x_hi - x_lo) * (x1 - x0); };
    auto py = [&](double y) { return y1 - (y - y_lo) / (y_hi - y_lo) * (y1 - y0); };
    const std::array<uint8_t, 3> grid{225, 225, 225}, axis{60, 60, 60};

    std::vector<double> yt = nice_ticks(y_lo, y_hi), xt = nice_ticks(x_lo, x_hi);
    double y_step = yt.size() > 1 ? yt[1] - yt[0] : 1, x_step = xt.size() > 1 ? xt[1] - xt[0] : 1;
    for (double v : yt) {
        int y = static_cast<int>(std::lround(py(v)));
        draw_line(image, x0, y, x1, y, grid, 1);
        std::string label = tick_label(v, y_step);
        draw_text(image, label, x0 - 8 - text_width(label, scale) / 2, y - 7, scale, axis);
    }
    for (double v : xt) {
        int x = static_cast<int>(std::lround(px(v)));
        draw_line(image, x, y0, x, y1, grid, 1);
        draw_text(image, tick_label(v, x_step), x, y1 + 6, scale, axis);
    }
    draw_line(image, x0, y1, x1, y1, axis, 2);
    draw_line(image, x0, y0, x0, y1, axis, 2);
    draw_text(image, plot.title, plot.width / 2, 8, scale, axis);
    draw_text(image, plot.x_label, (x0 + x1) / 2, plot.height - 28, scale, axis);
    // The y label goes above the axis, under the title (horizontal text only).
    draw_text(image, plot.y_label, 10 + text_width(plot.y_label, scale) / 2, 34, scale, axis);

    for (size_t k = 0; k < plot.series.size(); ++k) {
        const PlotSeries& s = plot.series[k];
        auto color = kPalette[k % kPalette.size()];
        bool have_previous = false;
        double prev_x = 0, prev_y = 0;
        for (size_t i = 0; i < s.x.size(); ++i) {
            if (!std::isfinite(s.x[i]) || !std::isfinite(s.y[i])) continue;
            double x = px(s.x[i]), y = py(s.y[i]);
            if (have_previous) draw_line(image, prev_x, prev_y, x, y, color, 3);
            fill_rect(image, static_cast<int>(x) - 4, static_cast<int>(y) - 4,
                      static_cast<int>(x) + 5, static_cast<int>(y) + 5, color);
            prev_x = x, prev_y = y, have_previous = true;
        }
        // Legend, top right, one line per series.
        int ly = y0 + 8 + 22 * static_cast<int>(k);
        fill_rect(image, x1 - 200, ly + 4, x1 - 180, ly + 10, color);
        draw_text(image, s.label, x1 - 172 + text_width(s.label, scale) / 2, ly, scale, axis);
    }
    return image;
}

}  // namespace pumeta
