#include "pumeta/eval/evaluate_cases.h"

#include <ATen/ATen.h>
#include <spdlog/spdlog.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <map>

#include "pumeta/core/error.h"
#include "pumeta/core/progress.h"
#include "pumeta/core/version.h"
#include "pumeta/data/layout.h"
#include "pumeta/eval/cases_csv.h"
#include "pumeta/eval/grid_floor.h"
#include "pumeta/eval/oracle.h"
#include "pumeta/geometry/io.h"
#include "pumeta/metrics/metrics.h"

namespace pumeta {

namespace fs = std::filesystem;

namespace {

struct Stats {
    std::vector<double> values;
    void add(double v) {
        if (std::isfinite(v)) values.push_back(v);
    }
    nlohmann::json summary() const {
        if (values.empty()) return nullptr;
        std::vector<double> sorted = values;
        std::sort(sorted.begin(), sorted.end());
        double sum = 0;
        for (double v : values) sum += v;
        size_t n = sorted.size();
        double median = n % 2 ? sorted[n / 2] : 0.5 * (sorted[n / 2 - 1] + sorted[n / 2]);
        return {{"mean", sum / n}, {"median", median}, {"count", n}};
    }
};

std::string shell_quote(const std::string& text) {
    std::string quoted = "'";
    for (char c : text) quoted += c == '\'' ? std::string("'\\''") : std::string(1, c);
    return quoted + "'";
}

void replace_all(std::string& text, const std::string& key, const std::string& value) {
    for (size_t at = text.find(key); at != std::string::npos;
         at = text.find(key, at + value.size()))
        text.replace(at, key.size(), value);
}

/// Runs an external upsampler on `input` through XYZ files in `work_dir`.
at::Tensor run_external(const std::string& command_template, const at::Tensor& input, int64_t ratio,
                        const fs::path& work_dir, const std::string& name) {
    fs::create_directories(work_dir);
    fs::path in = work_dir / (name + ".in.xyz"), out = work_dir / (name + ".out.xyz");
    write_point_cloud(in.string(), PointCloud{input, {}, {}});
    std::string command = command_template;
    replace_all(command, "{input}", shell_quote(in.string()));
    replace_all(command, "{output}", shell_quote(out.string()));
    replace_all(command, "{ratio}", std::to_string(ratio));
    int status =
        std::system((command + " 2>" + shell_quote((work_dir / "stderr.txt").string())).c_str());
    fs::remove(in);
    if (status != 0 || !fs::exists(out)) {
        std::ifstream err(work_dir / "stderr.txt");
        std::string first_line;
        std::getline(err, first_line);
        throw_input_error(name, "external upsampler failed (status {}): {}: {}", status, command,
                          first_line);
    }
    at::Tensor points = read_point_cloud(out.string()).points;
    fs::remove(out);
    return points;
}

}  // namespace

UpsampleResult predict_with_method(const Backbone* model, const at::Tensor& input,
                                   const at::Tensor& gt, const EvalOptions& options,
                                   const UpsampleOptions& upsample, const std::string& out_dir,
                                   const std::string& name) {
    const int64_t ratio = upsample.ratio;
    UpsampleResult result;
    auto start = std::chrono::steady_clock::now();
    if (options.method == "network") {
        // The diagnostic upper bound adapts on this case's ground truth (docs/design.md).
        result = options.oracle && upsample.adaptation.enabled()
                     ? upsample_with_oracle(*model, input, gt, upsample)
                     : upsample_cloud(*model, input, upsample);
    } else if (options.method == "zero-shot") {
        ZeroShotOptions zero_shot = options.zero_shot;
        zero_shot.seed = upsample.seed;
        ZeroShotResult trained = train_zero_shot(model->config(), input, zero_shot);
        UpsampleOptions plain = upsample;
        plain.adaptation = Adaptation();
        result = upsample_cloud(*trained.model, input, plain);
        result.seconds += trained.seconds;
        result.tta_seconds = trained.seconds;
        result.loss_before = trained.loss_first;
        result.loss_after = trained.loss_last;
    } else if (options.method == "midpoint") {
        result.points = midpoint_upsample(input, ratio);
    } else if (options.method == "external") {
        if (options.external_command.empty())
            throw_input_error("eval", "method 'external' needs a command");
        result.points = run_external(options.external_command, input, ratio,
                                     fs::path(out_dir) / "external", name);
    } else if (options.method == "input") {
        result.points = input;
    } else if (options.method == "grid-floor") {
        result.points = grid_floor_output(*model, input, gt, ratio);
    } else {
        throw_input_error("--method", "unknown method '{}'", options.method);
    }
    if (options.method != "network" && options.method != "zero-shot")
        result.seconds =
            std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    return result;
}

nlohmann::json evaluate_cases(const std::string& cases_dir, const Backbone* model,
                              const EvalOptions& options, const std::string& out_dir) {
    const nlohmann::json index = layout::read_case_index(cases_dir);
    if ((options.method == "network" || options.method == "zero-shot" ||
         options.method == "grid-floor") &&
        !model)
        throw_input_error("eval", "method '{}' needs --model", options.method);
    int64_t ratio = index.at("ratio");
    UpsampleOptions upsample = options.upsample;
    upsample.ratio = ratio;
    fs::create_directories(out_dir);
    auto saves = [&](size_t i) {
        return options.save_predictions || static_cast<int64_t>(i) < options.save_first;
    };
    if (options.save_predictions || options.save_first > 0)
        fs::create_directories(fs::path(out_dir) / "pred");

    std::vector<nlohmann::json> cases = index.at("cases").get<std::vector<nlohmann::json>>();
    if (options.max_cases > 0 && static_cast<int64_t>(cases.size()) > options.max_cases)
        cases.resize(options.max_cases);
    fs::path csv_tmp = fs::path(out_dir) / kCasesCsvTmpFile;
    std::map<std::string, std::vector<std::string>> finished;
    if (options.resume && fs::exists(csv_tmp)) finished = read_finished_rows(csv_tmp.string());
    std::ofstream csv(csv_tmp);
    csv << kCasesCsvHeader << "\n";
    Stats cd, hd, p2f, psnr, seconds, tta_seconds, loss_before, loss_after;
    int64_t improved_inner = 0;
    auto add_row = [&](const std::vector<std::string>& row) {
        write_cases_csv_row(csv, row);  // row by row: an interrupted run resumes after it
        cd.add(csv_value(row[3]));
        hd.add(csv_value(row[4]));
        p2f.add(csv_value(row[5]));
        psnr.add(csv_value(row[6]));
        seconds.add(csv_value(row[7]));
        tta_seconds.add(csv_value(row[8]));
        loss_before.add(csv_value(row[9]));
        loss_after.add(csv_value(row[10]));
        if (csv_value(row[10]) < csv_value(row[9])) ++improved_inner;
    };
    ProgressBar progress(static_cast<int64_t>(cases.size()), "eval");
    int64_t resumed = 0;
    for (size_t i = 0; i < cases.size(); ++i) {
        const nlohmann::json& c = cases[i];
        auto done = finished.find(c.at("name").get<std::string>());
        if (done != finished.end()) {
            add_row(done->second);
            ++resumed;
            continue;
        }
        fs::path dir = fs::path(cases_dir) / c.at("name").get<std::string>();
        std::string input_file = layout::kInputFile;
        if (!options.noise.empty()) {
            if (!c.contains("noisy_inputs") || !c["noisy_inputs"].contains(options.noise))
                throw_input_error(dir.string(), "no noisy input '{}'", options.noise);
            input_file = c["noisy_inputs"][options.noise];
        }
        at::Tensor input = read_point_cloud((dir / input_file).string()).points;
        at::Tensor gt = read_point_cloud((dir / layout::kGtFile).string()).points;
        TriangleMesh mesh;
        bool has_mesh = !c.value("mesh", nlohmann::json()).is_null();
        if (has_mesh) mesh = read_mesh((dir / c["mesh"].get<std::string>()).string());

        UpsampleResult result;
        if (options.method == "floor") {
            if (c.value("gt_alt", nlohmann::json()).is_null())
                throw_input_error(dir.string(), "case has no gt_alt.ply for the sampling floor");
            auto start = std::chrono::steady_clock::now();
            result.points =
                read_point_cloud((dir / c["gt_alt"].get<std::string>()).string()).points;
            result.seconds =
                std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
        } else {
            result = predict_with_method(model, input, gt, options, upsample, out_dir,
                                         c["name"].get<std::string>());
        }
        MetricReport m = evaluate(result.points, gt, has_mesh ? &mesh : nullptr);
        // Adaptation time, or the zero-shot model's training time.
        bool trains = options.upsample.adaptation.enabled() || options.method == "zero-shot";
        add_row({c["name"].get<std::string>(), std::to_string(input.size(0)),
                 std::to_string(m.n_pred), csv_number(m.cd), csv_number(m.hd),
                 csv_number(m.p2f ? *m.p2f : std::nan("")), csv_number(m.psnr),
                 csv_number(result.seconds), csv_number(trains ? result.tta_seconds : std::nan("")),
                 csv_number(result.loss_before), csv_number(result.loss_after)});
        if (saves(i))
            write_point_cloud(
                (fs::path(out_dir) / "pred" / (c["name"].get<std::string>() + ".ply")).string(),
                PointCloud{result.points, {}, {}});
        progress.update(static_cast<int64_t>(i + 1), fmt::format("CD {:.3e}", m.cd));
    }
    progress.finish();
    if (resumed > 0)
        spdlog::info("eval: {} of {} cases taken from the interrupted run in {}", resumed,
                     cases.size(), out_dir);
    csv.close();
    fs::rename(csv_tmp, fs::path(out_dir) / kCasesCsvFile);
    fs::remove_all(fs::path(out_dir) / "external");

    nlohmann::json summary = {{"cases_dir", cases_dir},
                              {"set", index.value("set", "")},
                              {"ratio", ratio},
                              {"method", options.method},
                              {"external_command", options.external_command},
                              {"noise", options.noise},
                              {"count", cases.size()},
                              {"cd", cd.summary()},
                              {"hd", hd.summary()},
                              {"p2f", p2f.summary()},
                              {"psnr", psnr.summary()},
                              {"seconds", seconds.summary()},
                              {"command", options.command_line}};
    if (options.method == "zero-shot") {
        summary["zero_shot"] = {{"steps", options.zero_shot.steps},
                                {"batch_patches", options.zero_shot.batch_patches},
                                {"lr", options.zero_shot.lr},
                                {"augment", options.zero_shot.augment},
                                {"training_seconds", tta_seconds.summary()},
                                {"loss_first", loss_before.summary()},
                                {"loss_last", loss_after.summary()}};
    } else if (options.upsample.adaptation.enabled()) {
        nlohmann::json tta = options.upsample.adaptation.to_json();
        if (options.oracle) tta["unit"] = "oracle";
        tta["seconds"] = tta_seconds.summary();
        tta["loss_before"] = loss_before.summary();
        tta["loss_after"] = loss_after.summary();
        tta["inner_loss_improved"] = improved_inner;
        summary["tta"] = tta;
    }
    summary["pumeta"] = build_info();
    std::ofstream(fs::path(out_dir) / "summary.json") << summary.dump(2) << "\n";
    return summary;
}

}  // namespace pumeta
