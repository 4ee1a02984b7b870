// Line plots as PNG images (for the report's Table II and V figures): axes with ticks and
// labels, one polyline with markers per series, a legend. Text is stb_easy_font (ASCII).
#pragma once

#include <array>
#include <string>
#include <vector>

#include "pumeta/render/render.h"

namespace pumeta {

struct PlotSeries {
    std::string label;
    std::vector<double> x, y;  ///< same length; non-finite points are skipped
};

struct LinePlot {
    std::string title, x_label, y_label;
    std::vector<PlotSeries> series;
    int width = 640;
    int height = 420;
};

/// InputError when a series' x and y differ in length.
Image render_line_plot(const LinePlot& plot);

/// "Nice" tick values covering [lo, hi]: steps of 1, 2 or 5 times a power of ten, about
/// `count` of them.
std::vector<double> nice_ticks(double lo, double hi, int count = 5);

}  // namespace pumeta
