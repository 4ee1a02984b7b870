#include "pumeta/eval/evaluate_benchmark.h"

#include <ATen/ATen.h>
#include <spdlog/spdlog.h>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <map>
#include <optional>

#include "pumeta/core/error.h"
#include "pumeta/core/progress.h"
#include "pumeta/core/version.h"
#include "pumeta/eval/benchmark_protocol.h"
#include "pumeta/eval/cases_csv.h"
#include "pumeta/geometry/io.h"

namespace pumeta {

namespace fs = std::filesystem;

namespace {

constexpr const char* kBenchmarkCsvHeader =
    "object,n_in,n_out,n_gt,cd_1e3,hd_1e3,hd_legacy_1e3,p2f_1e3,p2f_std_1e3,seconds";

/// The entries of `dir`, by name; InputError when it cannot be listed.
std::vector<fs::directory_entry> entries(const fs::path& dir) {
    std::error_code error;
    std::vector<fs::directory_entry> found;
    for (fs::directory_iterator it(dir, error), end; !error && it != end; it.increment(error))
        found.push_back(*it);
    if (error) throw_input_error(dir.string(), "cannot be listed ({})", error.message());
    std::sort(found.begin(), found.end(), [](const auto& a, const auto& b) {
        return a.path().filename() < b.path().filename();
    });
    return found;
}

bool is_xyz_file(const fs::directory_entry& entry) {
    std::string extension = entry.path().extension().string();
    std::transform(extension.begin(), extension.end(), extension.begin(),
                   [](unsigned char c) { return std::tolower(c); });
    std::error_code error;
    return extension == ".xyz" && entry.is_regular_file(error);
}

/// The folders under `dir` named <prefix><number>, by number.
std::map<int64_t, fs::path> numbered_folders(const fs::path& dir, const std::string& prefix) {
    std::map<int64_t, fs::path> found;
    for (const fs::directory_entry& entry : entries(dir)) {
        const std::string name = entry.path().filename().string();
        std::error_code error;
        if (name.rfind(prefix, 0) != 0 || !entry.is_directory(error)) continue;
        const std::string digits = name.substr(prefix.size());
        if (digits.empty() || digits.size() > 12 ||
            !std::all_of(digits.begin(), digits.end(),
                         [](unsigned char c) { return std::isdigit(c); }))
            continue;
        found[std::stoll(digits)] = entry.path();
    }
    return found;
}

std::string folder_names(const std::map<int64_t, fs::path>& folders) {
    std::string names;
    for (const auto& [number, path] : folders)
        names += (names.empty() ? "" : ", ") + path.filename().string();
    return names.empty() ? "none" : names;
}

/// `dir`, or dir/<its own name> when `dir` holds no .xyz file but that folder (PU1K nests its
/// test clouds so: input_2048/input_2048/).
fs::path clouds_folder(const fs::path& dir) {
    const std::vector<fs::directory_entry> listed = entries(dir);
    if (std::any_of(listed.begin(), listed.end(), is_xyz_file)) return dir;
    const fs::path nested = dir / dir.filename();
    std::error_code error;
    return fs::is_directory(nested, error) ? nested : dir;
}

/// Mean and population standard deviation of an object's P2F values (NaN without them).
std::pair<double, double> mean_and_std(const at::Tensor& values) {
    if (!values.defined() || values.numel() == 0) return {std::nan(""), std::nan("")};
    const at::Tensor d = values.to(at::kDouble);
    return {d.mean().item<double>(), d.std(/*unbiased=*/false).item<double>()};
}

}  // namespace

BenchmarkLayout find_benchmark_layout(const std::string& data_dir, int64_t input_points,
                                      int64_t ratio) {
    const fs::path root(data_dir);
    std::error_code error;
    if (!fs::exists(root, error)) throw_input_error(data_dir, "folder not found");
    if (!fs::is_directory(root, error)) throw_input_error(data_dir, "not a folder");

    const std::map<int64_t, fs::path> inputs = numbered_folders(root, "input_");
    if (inputs.empty())
        throw_input_error(data_dir,
                          "no input_<N> folder (the PU-GAN/PU1K test layout: input_2048/, "
                          "gt_8192/, original_meshes/)");
    int64_t n = input_points;
    if (n == 0 && inputs.size() == 1) n = inputs.begin()->first;
    if (n == 0 && inputs.count(2048)) n = 2048;
    if (n == 0)
        throw_input_error(data_dir, "several input folders ({}): choose one with --input-points",
                          folder_names(inputs));
    if (!inputs.count(n))
        throw_input_error(data_dir, "no input_{} folder (found: {})", n, folder_names(inputs));

    std::map<int64_t, fs::path> ratios;  // gt_<k·n> by k
    for (const auto& [m, path] : numbered_folders(root, "gt_"))
        if (m % n == 0 && m / n >= 2) ratios[m / n] = path;
    if (ratio == 0) {
        if (ratios.empty())
            throw_input_error(data_dir, "no gt_<k·{}> folder of ground truths for input_{}", n, n);
        if (ratios.size() > 1)
            throw_input_error(data_dir,
                              "several ground truths for input_{} ({}): choose one with --ratio", n,
                              folder_names(ratios));
        ratio = ratios.begin()->first;
    }
    if (!ratios.count(ratio))
        throw_input_error(data_dir, "no gt_{} folder for ratio {} (found: {})", ratio * n, ratio,
                          folder_names(ratios));

    BenchmarkLayout layout;
    layout.data_dir = data_dir;
    layout.input_points = n;
    layout.ratio = ratio;
    const fs::path input_dir = clouds_folder(inputs.at(n));
    const fs::path gt_dir = clouds_folder(ratios.at(ratio));
    layout.input_dir = input_dir.string();
    layout.gt_dir = gt_dir.string();
    for (const fs::directory_entry& entry : entries(input_dir)) {
        if (!is_xyz_file(entry)) continue;
        BenchmarkObject object;
        object.name = entry.path().stem().string();
        object.input = entry.path().string();
        const fs::path gt = gt_dir / (object.name + ".xyz");
        if (!fs::is_regular_file(gt, error))
            throw_input_error(gt_dir.string(), "no ground truth {}.xyz for {}", object.name,
                              object.input);
        object.gt = gt.string();
        for (const fs::path& dir : {root / "original_meshes", root}) {
            const fs::path mesh = dir / (object.name + ".off");
            if (fs::is_regular_file(mesh, error)) {
                object.mesh = mesh.string();
                break;
            }
        }
        layout.objects.push_back(object);
    }
    if (layout.objects.empty()) throw_input_error(layout.input_dir, "no .xyz files");
    return layout;
}

nlohmann::json evaluate_benchmark(const BenchmarkLayout& layout, const Backbone* model,
                                  const EvalOptions& options, const std::string& out_dir) {
    if (options.method == "floor")
        throw_input_error("eval",
                          "method 'floor' needs the second GT sample of pumeta's own cases; a "
                          "benchmark folder has none");
    if ((options.method == "network" || options.method == "zero-shot" ||
         options.method == "grid-floor") &&
        !model)
        throw_input_error("eval", "method '{}' needs --model", options.method);
    UpsampleOptions upsample = options.upsample;
    upsample.ratio = layout.ratio;
    std::vector<BenchmarkObject> objects = layout.objects;
    if (options.max_cases > 0 && static_cast<int64_t>(objects.size()) > options.max_cases)
        objects.resize(options.max_cases);

    fs::create_directories(out_dir);
    if (options.save_predictions) fs::create_directories(fs::path(out_dir) / "pred");
    const fs::path csv_tmp = fs::path(out_dir) / kCasesCsvTmpFile;
    std::ofstream csv(csv_tmp);
    csv << kBenchmarkCsvHeader << "\n";
    BenchmarkTally tally;
    double seconds = 0;
    std::vector<std::string> without_mesh;
    ProgressBar progress(static_cast<int64_t>(objects.size()), "eval");
    for (size_t i = 0; i < objects.size(); ++i) {
        const BenchmarkObject& object = objects[i];
        const at::Tensor input = read_point_cloud(object.input).points;
        const at::Tensor gt = read_point_cloud(object.gt).points;
        std::optional<TriangleMesh> mesh;
        if (!object.mesh.empty())
            mesh = read_mesh(object.mesh);
        else
            without_mesh.push_back(object.name);
        const UpsampleResult result =
            predict_with_method(model, input, gt, options, upsample, out_dir, object.name);
        const BenchmarkScores scores =
            score_benchmark_object(result.points, gt, mesh ? &*mesh : nullptr);
        tally.add(scores);
        seconds += result.seconds;
        const auto [p2f, p2f_std] = mean_and_std(scores.p2f);
        write_cases_csv_row(
            csv, {object.name, std::to_string(input.size(0)), std::to_string(result.points.size(0)),
                  std::to_string(gt.size(0)), csv_number(scores.cd * 1e3),
                  csv_number(scores.hd * 1e3), csv_number(scores.hd_legacy * 1e3),
                  csv_number(p2f * 1e3), csv_number(p2f_std * 1e3), csv_number(result.seconds)});
        if (options.save_predictions)
            write_point_cloud((fs::path(out_dir) / "pred" / (object.name + ".xyz")).string(),
                              PointCloud{result.points, {}, {}});
        progress.update(static_cast<int64_t>(i + 1), fmt::format("CD {:.4f}e-3", scores.cd * 1e3));
    }
    progress.finish();
    csv.close();
    fs::rename(csv_tmp, fs::path(out_dir) / kCasesCsvFile);
    fs::remove_all(fs::path(out_dir) / "external");

    auto number = [](double v) { return std::isfinite(v) ? nlohmann::json(v) : nlohmann::json(); };
    nlohmann::json summary = {
        {"benchmark", layout.benchmark},
        {"data_dir", layout.data_dir},
        {"input_dir", layout.input_dir},
        {"gt_dir", layout.gt_dir},
        {"input_points", layout.input_points},
        {"ratio", layout.ratio},
        {"method", options.method},
        {"objects", tally.objects()},
        {"objects_with_mesh", tally.objects_with_mesh()},
        {"p2f_points", tally.p2f_points()},
        {"cd_1e3", number(tally.cd() * 1e3)},
        {"hd_1e3", number(tally.hd() * 1e3)},
        {"hd_legacy_1e3", number(tally.hd_legacy() * 1e3)},
        {"p2f_1e3", number(tally.p2f_mean() * 1e3)},
        {"p2f_std_1e3", number(tally.p2f_std() * 1e3)},
        {"seconds", objects.empty() ? nlohmann::json() : nlohmann::json(seconds / objects.size())},
        {"protocol", benchmark_protocol_description()},
        {"command", options.command_line}};
    if (options.method == "external") summary["external_command"] = options.external_command;
    if (options.upsample.adaptation.enabled())
        summary["tta"] = options.upsample.adaptation.to_json();
    if (!without_mesh.empty()) {
        const std::string note = fmt::format(
            "P2F omitted for {} of {} objects without a mesh <name>.off in {} or "
            "original_meshes/ (first: {})",
            without_mesh.size(), objects.size(), layout.data_dir, without_mesh.front());
        summary["note"] = note;
        spdlog::warn("eval: {}", note);
    }
    summary["pumeta"] = build_info();
    std::ofstream(fs::path(out_dir) / "summary.json") << summary.dump(2) << "\n";
    return summary;
}

}  // namespace pumeta
