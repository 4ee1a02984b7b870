#include "pumeta/eval/report.h"

#include <ATen/ATen.h>
#include <spdlog/spdlog.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <map>
#include <nlohmann/json.hpp>
#include <sstream>

#include "pumeta/core/error.h"
#include "pumeta/data/layout.h"
#include "pumeta/eval/cases_csv.h"
#include "pumeta/geometry/io.h"
#include "pumeta/geometry/knn.h"
#include "pumeta/render/plot.h"
#include "pumeta/render/render.h"

namespace pumeta {

namespace fs = std::filesystem;

namespace {

std::string escape_html(const std::string& text) {
    std::string out;
    for (char c : text) {
        switch (c) {
            case '&':
                out += "&amp;";
                break;
            case '<':
                out += "&lt;";
                break;
            case '>':
                out += "&gt;";
                break;
            case '"':
                out += "&quot;";
                break;
            default:
                out += c;
        }
    }
    return out;
}

// Inline markdown of our own tables.md: `code` spans only.
std::string inline_html(const std::string& text) {
    std::string out, escaped = escape_html(text);
    bool code = false;
    for (char c : escaped) {
        if (c == '`') {
            out += code ? "</code>" : "<code>";
            code = !code;
        } else {
            out += c;
        }
    }
    if (code) out += "</code>";
    return out;
}

std::vector<std::string> table_cells(const std::string& line) {
    std::vector<std::string> cells;
    std::string cell;
    for (size_t i = 1; i < line.size(); ++i) {
        if (line[i] == '|') {
            size_t a = cell.find_first_not_of(' '), b = cell.find_last_not_of(' ');
            cells.push_back(a == std::string::npos ? "" : cell.substr(a, b - a + 1));
            cell.clear();
        } else {
            cell += line[i];
        }
    }
    return cells;
}

/// The subset of markdown that reproduce writes: # headings, paragraphs, pipe tables, "- "
/// lists and `code`.
std::string markdown_to_html(const std::string& markdown) {
    std::ostringstream html;
    std::istringstream in(markdown);
    std::string line;
    enum class Block { none, paragraph, table, list } block = Block::none;
    int table_row = 0;
    auto close = [&] {
        if (block == Block::paragraph) html << "</p>\n";
        if (block == Block::table) html << "</tbody></table>\n";
        if (block == Block::list) html << "</ul>\n";
        block = Block::none;
    };
    while (std::getline(in, line)) {
        if (line.empty()) {
            close();
        } else if (line.rfind("#", 0) == 0) {
            close();
            size_t level = line.find_first_not_of('#');
            html << "<h" << level << ">" << inline_html(line.substr(level + 1)) << "</h" << level
                 << ">\n";
        } else if (line.rfind("|", 0) == 0) {
            if (block != Block::table) {
                close();
                html << "<table><thead>";
                block = Block::table;
                table_row = 0;
            }
            std::vector<std::string> cells = table_cells(line);
            if (table_row == 1) {  // the |---| rule
                html << "</thead><tbody>";
            } else {
                const char* tag = table_row == 0 ? "th" : "td";
                html << "<tr>";
                for (const std::string& c : cells)
                    html << "<" << tag << ">" << inline_html(c) << "</" << tag << ">";
                html << "</tr>";
            }
            ++table_row;
        } else if (line.rfind("- ", 0) == 0) {
            if (block != Block::list) {
                close();
                html << "<ul>\n";
                block = Block::list;
            }
            html << "<li>" << inline_html(line.substr(2)) << "</li>\n";
        } else {
            if (block != Block::paragraph) {
                close();
                html << "<p>";
                block = Block::paragraph;
            } else {
                html << " ";
            }
            html << inline_html(line);
        }
    }
    close();
    return html.str();
}

struct Method {
    std::string label;
    fs::path run;  // the run directory of this set
};

/// The Table I methods of one set (sampling floor left out: it is a second GT sample).
std::vector<Method> table1_methods(const nlohmann::json& tables, const fs::path& results,
                                   const std::string& set) {
    std::vector<Method> methods;
    for (const nlohmann::json& row : tables.at("table1").at("rows")) {
        std::string label = row.at("label");
        if (label.rfind("sampling floor", 0) == 0) continue;
        for (const nlohmann::json& cell : row.at("cells"))
            if (cell.at("group") == set && cell.contains("run") && !cell.contains("missing")) {
                methods.push_back({label, results / cell["run"].get<std::string>()});
                break;
            }
    }
    return methods;
}

at::Tensor nearest_distances(const at::Tensor& gt, const at::Tensor& points) {
    return knn(gt, points, 1).sq_distances.squeeze(1).sqrt();
}

std::string short_label(std::string label) {
    if (label == "input, unchanged") return "input";
    if (label == "midpoint baseline") return "midpoint";
    size_t paren = label.find(" (");
    return paren == std::string::npos ? label : label.substr(0, paren);
}

double parse_noise(const std::string& group) {
    if (group == "clean") return 0;
    if (group.rfind("rel", 0) == 0) return std::stod(group.substr(3));
    return std::nan("");
}

}  // namespace

ReportSummary write_report(const std::string& results_dir, const std::string& out_dir) {
    fs::path results(results_dir), out(out_dir);
    fs::path tables_file = results / "tables.json";
    if (!fs::exists(tables_file))
        throw_input_error(results_dir,
                          "no tables.json: not an output directory of pumeta reproduce");
    nlohmann::json tables = nlohmann::json::parse(std::ifstream(tables_file), nullptr, false);
    if (tables.is_discarded() || !tables.contains("markdown") || !tables.contains("config"))
        throw_input_error(tables_file.string(), "not a tables.json of pumeta reproduce");
    const nlohmann::json& config = tables["config"];
    fs::create_directories(out / "figures");
    ReportSummary summary;
    std::ostringstream figures_html;

    // ---- Objects: input / each method / GT, with per-point error colouring below --------
    const int64_t ratio = config.at("main_ratio");
    const int64_t per_set = config.value("figure_cases", int64_t{4});
    const int size = 300;
    figures_html << "<h2>Objects (" << ratio << "×)</h2>\n<p>Top row: each method's output, "
                 << "then the GT. Bottom row: the same points coloured by their distance to the "
                    "nearest GT point (dark = close, yellow = at or above the 95th percentile "
                    "of all methods' distances on that object).</p>\n";
    for (const std::string& set : config.at("sets").get<std::vector<std::string>>()) {
        std::vector<Method> methods = table1_methods(tables, results, set);
        if (methods.empty()) continue;
        fs::path cases_dir = layout::cases_dir(
            tables.value("dataset_path", config.at("dataset_dir").get<std::string>()), set, ratio);
        for (const std::string& name :
             first_case_names((methods.front().run / kCasesCsvFile).string(), per_set)) {
            fs::path gt_file = cases_dir / name / layout::kGtFile;
            if (!fs::exists(gt_file)) {
                spdlog::warn("report: {} not found: no figure for {}", gt_file.string(), name);
                continue;
            }
            at::Tensor gt = read_point_cloud(gt_file.string()).points;
            RenderOptions options;
            options.width = options.height = size;
            options.frame = fit_frame(gt);
            std::vector<std::string> labels;
            std::vector<at::Tensor> clouds, errors;
            for (const Method& m : methods) {
                fs::path pred = m.run / "pred" / (name + ".ply");
                if (!fs::exists(pred)) continue;
                at::Tensor points = read_point_cloud(pred.string()).points;
                clouds.push_back(points);
                errors.push_back(nearest_distances(gt, points));
                labels.push_back(short_label(m.label));
            }
            if (clouds.empty()) continue;
            std::vector<at::Tensor> colors = error_colors(errors);
            std::vector<Image> top, bottom;
            for (size_t i = 0; i < clouds.size(); ++i) {
                top.push_back(render_image(clouds[i], options));
                bottom.push_back(render_image(clouds[i], options, colors[i]));
            }
            top.push_back(render_image(gt, options));
            bottom.push_back(Image(size, size));
            std::vector<Image> cells = top;
            cells.insert(cells.end(), bottom.begin(), bottom.end());
            std::vector<std::string> cell_labels = labels;
            cell_labels.push_back("GT");
            for (size_t i = 0; i < labels.size(); ++i) cell_labels.push_back(labels[i] + " error");
            std::string file = "figures/" + set + "-" + name + ".png";
            write_png((out / file).string(),
                      render_grid(cells, static_cast<int>(top.size()), cell_labels));
            figures_html << "<figure><img src=\"" << escape_html(file) << "\" alt=\""
                         << escape_html(set + " " + name) << "\"><figcaption>"
                         << escape_html(set + ": " + name) << " (" << gt.size(0)
                         << " GT points)</figcaption></figure>\n";
            ++summary.object_figures;
        }
    }

    // ---- Plots ----------------------------------------------------------------------------
    figures_html << "<h2>Plots</h2>\n";
    auto mean_of = [](const nlohmann::json& cell) {
        return cell.at("mean").is_number() ? cell["mean"].get<double>() : std::nan("");
    };
    auto write_plot = [&](const LinePlot& plot, const std::string& file) {
        write_png((out / file).string(), render_line_plot(plot));
        figures_html << "<figure><img src=\"" << file << "\" alt=\"" << escape_html(plot.title)
                     << "\"></figure>\n";
        ++summary.plots;
    };
    if (tables.contains("table5") &&
        !tables["table5"].value("rows", nlohmann::json::array()).empty()) {
        // Rows "<backbone>, plain" then "<backbone> + ours, N = k".
        std::map<std::string, PlotSeries> cd, time;
        std::vector<std::string> order;
        for (const nlohmann::json& row : tables["table5"]["rows"]) {
            std::string label = row.at("label");
            size_t plain = label.find(", plain"), n_at = label.find("N = ");
            std::string backbone =
                label.substr(0, plain != std::string::npos ? plain : label.find(" + "));
            double n = plain != std::string::npos ? 0 : std::stod(label.substr(n_at + 4));
            if (!cd.count(backbone)) order.push_back(backbone);
            for (const nlohmann::json& cell : row.at("cells")) {
                PlotSeries* series = cell.at("metric") == "cd"        ? &cd[backbone]
                                     : cell.at("metric") == "seconds" ? &time[backbone]
                                                                      : nullptr;
                if (!series) continue;
                series->label = backbone;
                series->x.push_back(n);
                series->y.push_back(mean_of(cell) * (cell["metric"] == "cd" ? 1e4 : 1e3));
            }
        }
        LinePlot cd_plot{
            "Table V: CD after N adaptation steps (N = 0: plain)", "N", "CD (x1e-4)", {}};
        LinePlot time_plot{"Table V: time per object", "N", "ms per object", {}};
        for (const std::string& b : order) {
            cd_plot.series.push_back(cd[b]);
            time_plot.series.push_back(time[b]);
        }
        write_plot(cd_plot, "figures/table5-cd.png");
        write_plot(time_plot, "figures/table5-time.png");
    }
    if (tables.contains("table2") &&
        !tables["table2"].value("rows", nlohmann::json::array()).empty()) {
        LinePlot noise_plot{"Table II: CD vs input noise",
                            "noise (% of the bounding-box diagonal)",
                            "CD (x1e-4)",
                            {}};
        for (const nlohmann::json& row : tables["table2"]["rows"]) {
            PlotSeries series{row.at("label").get<std::string>(), {}, {}};
            for (const nlohmann::json& cell : row.at("cells")) {
                series.x.push_back(parse_noise(cell.at("group")));
                series.y.push_back(mean_of(cell) * 1e4);
            }
            noise_plot.series.push_back(series);
        }
        write_plot(noise_plot, "figures/table2-noise.png");
    }

    // ---- The page -------------------------------------------------------------------------
    std::ostringstream html;
    html << "<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\">\n"
         << "<title>pumeta results</title>\n<style>\n"
         << "body{font-family:sans-serif;max-width:1400px;margin:2em auto;padding:0 1em;"
            "color:#222;line-height:1.45}\n"
         << "table{border-collapse:collapse;margin:1em 0;font-size:90%}\n"
         << "th,td{border:1px solid #bbb;padding:3px 8px;text-align:right}\n"
         << "th:first-child,td:first-child{text-align:left}\n"
         << "thead{background:#eef}\nfigure{margin:1.5em 0}\nimg{max-width:100%}\n"
         << "code{background:#f4f4f4;padding:0 3px}\n#image-check{color:#666}\n"
         << "</style></head><body>\n"
         << markdown_to_html(tables.at("markdown").get<std::string>()) << figures_html.str()
         << "<p id=\"image-check\">image check pending</p>\n"
         << "<script>\nwindow.addEventListener('load', function () {\n"
            "  var images = document.images, broken = [];\n"
            "  for (var i = 0; i < images.length; ++i)\n"
            "    if (!images[i].complete || images[i].naturalWidth === 0)\n"
            "      broken.push(images[i].getAttribute('src'));\n"
            "  document.getElementById('image-check').textContent = broken.length\n"
            "    ? 'images: ' + broken.length + ' broken: ' + broken.join(' ')\n"
            "    : 'images: all ' + images.length + ' loaded';\n"
            "});\n</script>\n</body></html>\n";
    std::string tmp = (out / "index.html.tmp").string();
    std::ofstream(tmp) << html.str();
    fs::rename(tmp, out / "index.html");
    return summary;
}

}  // namespace pumeta
