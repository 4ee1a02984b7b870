#include "pumeta/eval/reproduce_config.h"

#include <algorithm>
#include <filesystem>

#include "pumeta/core/error.h"
#include "pumeta/core/json_fields.h"

namespace pumeta {

namespace fs = std::filesystem;

namespace {

constexpr const char* kContext = "reproduce config";

}  // namespace

std::string with_bindir(std::string command) {
    const std::string bindir = fs::read_symlink("/proc/self/exe").parent_path().string();
    for (size_t at = command.find("{bindir}"); at != std::string::npos;
         at = command.find("{bindir}", at + bindir.size()))
        command.replace(at, 8, bindir);
    return command;
}

template <class Self, class Visit>
void external_baseline_fields(Self& b, Visit&& visit) {
    visit("label", b.label);
    visit("command", b.command);
}

ExternalBaseline ExternalBaseline::from_json(const nlohmann::json& j) {
    ExternalBaseline b;
    read_fields(j, "reproduce config: external baseline",
                [&](auto&& visit) { external_baseline_fields(b, visit); });
    if (b.label.empty() || b.command.empty())
        throw_input_error(kContext, "each external baseline needs a 'label' and a 'command'");
    return b;
}

nlohmann::json ExternalBaseline::to_json() const {
    return write_fields([&](auto&& visit) { external_baseline_fields(*this, visit); });
}

template <class Self, class Visit>
void reference_model_fields(Self& m, Visit&& visit) {
    visit("label", m.label);
    visit("model", m.model);
    visit("tta_lr", m.tta_lr);
    visit("meta_model", m.meta_model);
}

ReferenceModel ReferenceModel::from_json(const nlohmann::json& j) {
    ReferenceModel m;
    read_fields(j, "reproduce config: reference model",
                [&](auto&& visit) { reference_model_fields(m, visit); });
    if (m.label.empty() || m.model.empty())
        throw_input_error(kContext, "each reference model needs a 'label' and a 'model'");
    if (m.tta_lr < 0)
        throw_input_error(kContext, "reference model '{}': 'tta_lr' must not be negative", m.label);
    return m;
}

nlohmann::json ReferenceModel::to_json() const {
    return write_fields([&](auto&& visit) { reference_model_fields(*this, visit); });
}

template <class Self, class Visit>
void public_benchmark_fields(Self& b, Visit&& visit) {
    visit("name", b.name);
    visit("label", b.label);
    visit("data_dir", b.data_dir);
    visit("input_points", b.input_points);
    visit("ratios", b.ratios);
}

PublicBenchmark PublicBenchmark::from_json(const nlohmann::json& j) {
    PublicBenchmark b;
    read_fields(j, "reproduce config: benchmark",
                [&](auto&& visit) { public_benchmark_fields(b, visit); });
    if (b.name.empty() || b.data_dir.empty())
        throw_input_error(kContext, "each benchmark needs a 'name' and a 'data_dir'");
    if (b.label.empty()) b.label = b.name;
    if (b.ratios.empty() || *std::min_element(b.ratios.begin(), b.ratios.end()) < 2)
        throw_input_error(kContext, "benchmark '{}': 'ratios' must be at least 2", b.name);
    return b;
}

nlohmann::json PublicBenchmark::to_json() const {
    return write_fields([&](auto&& visit) { public_benchmark_fields(*this, visit); });
}

template <class Self, class Visit>
void zero_shot_fields(Self& z, Visit&& visit) {
    visit("steps", z.steps);
    visit("batch_patches", z.batch_patches);
    visit("lr", z.lr);
    visit("max_cases", z.max_cases);
    visit("backbones", z.backbones);
}

ZeroShotBaseline ZeroShotBaseline::from_json(const nlohmann::json& j) {
    ZeroShotBaseline z;
    read_fields(j, "reproduce config: zero_shot",
                [&](auto&& visit) { zero_shot_fields(z, visit); });
    if (z.steps < 1 || z.batch_patches < 1 || z.lr <= 0 || z.max_cases < 0)
        throw_input_error(kContext, "zero_shot: steps, batch_patches, lr must be positive");
    return z;
}

nlohmann::json ZeroShotBaseline::to_json() const {
    return write_fields([&](auto&& visit) { zero_shot_fields(*this, visit); });
}

template <class Self, class Visit>
void reproduce_fields(Self& c, Visit&& visit) {
    visit("dataset_dir", c.dataset_dir);
    visit("models_dir", c.models_dir);
    visit("backbones", c.backbones);
    visit("backbone_labels", c.backbone_labels);
    visit("external_baselines", c.external_baselines);
    visit("reference_models", c.reference_models);
    visit("main_ratio", c.main_ratio);
    visit("table3_ratios", c.table3_ratios);
    visit("any_ratios", c.any_ratios);
    visit("any_ratio_backbones", c.any_ratio_backbones);
    visit("scan_sets", c.scan_sets);
    visit("scan_ratios", c.scan_ratios);
    visit("sets", c.sets);
    visit("noise", c.noise);
    visit("noise_backbones", c.noise_backbones);
    visit("tta_steps", c.tta_steps);
    visit("tta_unit", c.tta_unit);
    visit("steps_sweep", c.steps_sweep);
    visit("sweep_backbones", c.sweep_backbones);
    visit("tta_lr_without_meta", c.tta_lr_without_meta);
    visit("seed", c.seed);
    visit("bootstrap_resamples", c.bootstrap_resamples);
    visit("max_cases", c.max_cases);
    visit("figure_cases", c.figure_cases);
    visit("zero_shot", c.zero_shot);
    visit("paper_tables", c.paper_tables);
    visit("benchmarks", c.benchmarks);
}

ReproduceConfig ReproduceConfig::from_json(nlohmann::json j, const std::string& budget) {
    if (!j.is_object()) throw_input_error(kContext, "expected a JSON object");
    if (j.contains("budgets")) {
        if (!j["budgets"].contains(budget))
            throw_input_error(kContext, "no budget '{}' in 'budgets'", budget);
        for (const auto& [key, value] : j["budgets"][budget].items()) j[key] = value;
        j.erase("budgets");
    } else if (budget != "full") {
        throw_input_error(kContext, "budget '{}' needs a 'budgets' object", budget);
    }
    ReproduceConfig c;
    c.budget = budget;
    read_fields(j, kContext, [&](auto&& visit) { reproduce_fields(c, visit); });
    if (c.main_ratio < 2) throw_input_error(kContext, "'main_ratio' must be at least 2");
    if (c.tta_steps < 1) throw_input_error(kContext, "'tta_steps' must be positive");
    if (c.tta_unit != "object" && c.tta_unit != "patch" && c.tta_unit != "cloud")
        throw_input_error(kContext, "'tta_unit' must be \"object\", \"patch\" or \"cloud\"");
    if (c.sets.empty()) throw_input_error(kContext, "'sets' is empty");
    for (const PublicBenchmark& b : c.benchmarks)
        if (std::count(c.sets.begin(), c.sets.end(), b.name) ||
            std::count(c.scan_sets.begin(), c.scan_sets.end(), b.name))
            throw_input_error(kContext, "benchmark '{}' has the name of a test set", b.name);
    return c;
}

nlohmann::json ReproduceConfig::to_json() const {
    nlohmann::json j = write_fields([&](auto&& visit) { reproduce_fields(*this, visit); });
    j["budget"] = budget;
    return j;
}

std::optional<double> ReproduceConfig::tta_lr_for(const std::string& backbone,
                                                  int64_t ratio) const {
    for (const std::string& key : {backbone + "-x" + std::to_string(ratio), backbone}) {
        auto it = tta_lr_without_meta.find(key);
        if (it != tta_lr_without_meta.end()) return it->second;
    }
    return std::nullopt;
}

const PublicBenchmark* ReproduceConfig::benchmark(const std::string& set) const {
    for (const PublicBenchmark& b : benchmarks)
        if (b.name == set) return &b;
    return nullptr;
}

std::string ReproduceConfig::label_of(const std::string& backbone) const {
    auto it = backbone_labels.find(backbone);
    return it != backbone_labels.end() ? it->second : backbone;
}

}  // namespace pumeta
