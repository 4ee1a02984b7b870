#include "pumeta/eval/reproduce.h"

#include <fcntl.h>
#include <spdlog/spdlog.h>
#include <unistd.h>

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <chrono>
#include <cmath>
#include <csignal>
#include <filesystem>
#include <fstream>
#include <functional>
#include <optional>
#include <set>
#include <sstream>
#include <thread>

#include "pumeta/core/error.h"
#include "pumeta/core/json_fields.h"
#include "pumeta/core/sha256.h"
#include "pumeta/eval/evaluate_cases.h"
#include "pumeta/eval/paired_stats.h"
#include "pumeta/geometry/io/file.h"
#include "pumeta/inference/model_file.h"
#include "pumeta/models/checkpoint.h"

namespace pumeta {

namespace fs = std::filesystem;

namespace {

constexpr const char* kContext = "reproduce config";

std::string display_name(const std::string& backbone) {
    if (backbone == "pugcn") return "PU-GCN";
    if (backbone == "dispu") return "Dis-PU";
    if (backbone == "pudense") return "PU-Dense";
    return backbone;
}

/// `command` with every "{bindir}" replaced by the directory of this executable.
std::string with_bindir(std::string command) {
    const std::string bindir = fs::read_symlink("/proc/self/exe").parent_path().string();
    for (size_t at = command.find("{bindir}"); at != std::string::npos;
         at = command.find("{bindir}", at + bindir.size()))
        command.replace(at, 8, bindir);
    return command;
}

// ---------------------------------------------------------------------------------------------
// One evaluation: a method on the cases of one set at one ratio.

struct RunSpec {
    std::string set;
    int64_t ratio = 0;
    std::string method = "network";  // network, midpoint, input, floor
    std::string model;               // network: checkpoint file
    int64_t tta_steps = 0;
    double tta_lr = -1;          // < 0: the model's own step sizes
    std::string noise;           // "" = clean input
    std::string label, command;  // external: the baseline's label and command ({bindir} kept)
    int64_t max_cases = -1;      // < 0: the config's max_cases
    ZeroShotBaseline zero_shot;  // method zero-shot (model: the architecture's checkpoint)

    std::string directory() const {
        std::string name = method == "network" ? fs::path(model).stem().string() : method;
        if (method == "zero-shot")
            name =
                fmt::format("zero-shot-{}.s{}", fs::path(model).stem().string(), zero_shot.steps);
        if (method == "external") {
            name = "external-";
            for (char c : label)
                name += std::isalnum(static_cast<unsigned char>(c)) ? char(std::tolower(c)) : '-';
        }
        if (method == "network") name += tta_steps > 0 ? ".tta" + std::to_string(tta_steps) : "";
        if (tta_lr >= 0) name += fmt::format(".lr{:g}", tta_lr);
        if (max_cases >= 0) name += fmt::format(".first{}", max_cases);
        std::string cases = set + "-x" + std::to_string(ratio) + (noise.empty() ? "" : "-" + noise);
        return cases + "/" + name;
    }
};

struct RunResult {
    std::string dir;  // relative to the output directory
    bool ok = false;
    std::string error;  // why there are no scores
    std::vector<std::string> cases;
    std::map<std::string, std::vector<double>> scores;  // column -> per case
    nlohmann::json summary;

    double mean(const std::string& column) const {
        if (!ok || !scores.count(column)) return std::nan("");
        double sum = 0;
        int64_t n = 0;
        for (double v : scores.at(column))
            if (std::isfinite(v)) sum += v, ++n;
        return n ? sum / n : std::nan("");
    }
};

double parse_number(const std::string& text) {
    if (text.empty()) return std::nan("");
    try {
        return std::stod(text);
    } catch (const std::exception&) {
        return std::nan("");
    }
}

// cases.csv of evaluate_cases: a header line, then one row per case (empty = NaN).
void read_cases_csv(const fs::path& file, RunResult& result) {
    std::ifstream in(file);
    std::string line;
    if (!std::getline(in, line)) throw_input_error(file.string(), "empty cases.csv");
    std::vector<std::string> header;
    std::stringstream head(line);
    for (std::string field; std::getline(head, field, ',');) header.push_back(field);
    while (std::getline(in, line)) {
        std::vector<std::string> fields;
        std::stringstream row(line);
        for (std::string field; std::getline(row, field, ',');) fields.push_back(field);
        fields.resize(header.size());
        result.cases.push_back(fields[0]);
        for (size_t i = 1; i < header.size(); ++i)
            result.scores[header[i]].push_back(parse_number(fields[i]));
    }
}

/// An exclusive claim on one cell, so that several `pumeta reproduce` processes with the same
/// output directory can share the work: the file <cell>.lock holds the owner's host and pid
/// and is created with O_EXCL. A lock of a process of this host that no longer runs is stale
/// and taken over.
class CellLock {
  public:
    static std::optional<CellLock> try_claim(const fs::path& file) {
        fs::create_directories(file.parent_path());
        const std::string owner = fmt::format("{} {}", host_name(), getpid());
        for (int attempt = 0; attempt < 2; ++attempt) {
            int fd = ::open(file.c_str(), O_CREAT | O_EXCL | O_WRONLY, 0644);
            if (fd >= 0) {
                bool written = ::write(fd, owner.data(), owner.size()) == ssize_t(owner.size());
                ::close(fd);
                if (!written) throw InternalError("cannot write " + file.string());
                return CellLock(file);
            }
            if (errno != EEXIST) throw InternalError("cannot create " + file.string());
            std::string host;
            long pid = 0;
            std::ifstream(file) >> host >> pid;
            bool alive =
                host != host_name() || pid <= 0 || ::kill(pid_t(pid), 0) == 0 || errno != ESRCH;
            if (alive) return std::nullopt;
            spdlog::warn("reproduce: taking over {} (process {} has ended)", file.string(), pid);
            fs::remove(file);
        }
        return std::nullopt;
    }
    CellLock(CellLock&& other) noexcept : file_(std::move(other.file_)) { other.file_.clear(); }
    CellLock& operator=(CellLock&& other) noexcept {
        release();
        file_ = std::move(other.file_);
        other.file_.clear();
        return *this;
    }
    ~CellLock() { release(); }

  private:
    explicit CellLock(fs::path file) : file_(std::move(file)) {}
    void release() {
        std::error_code ignored;
        if (!file_.empty()) fs::remove(file_, ignored);
    }
    static std::string host_name() {
        char name[256] = {};
        gethostname(name, sizeof name - 1);
        return name[0] ? name : "localhost";
    }
    fs::path file_;
};

class Runner {
  public:
    Runner(const ReproduceConfig& config, fs::path out_dir, std::string command_line, bool evaluate)
        : config_(config),
          out_dir_(std::move(out_dir)),
          command_line_(std::move(command_line)),
          evaluate_(evaluate) {}

    /// Cells that `--tables-only` left out because they were not evaluated yet.
    const std::set<std::string>& pending() const { return pending_; }

    fs::path cases_dir(const std::string& set, int64_t ratio) const {
        return fs::path(config_.dataset_dir) / "cases" / set / ("x" + std::to_string(ratio));
    }

    /// The checkpoint of a backbone at a ratio: <bb>-x<r>[-meta].pt, else a model of a smaller
    /// ratio that the pipeline can apply repeatedly (16× = 4× twice), else the main ratio's
    /// model when its weights serve any ratio (PU-Dense; load_inference_model rebuilds it).
    std::optional<std::string> model_file(const std::string& backbone, int64_t ratio,
                                          bool meta) const {
        const std::string suffix = meta ? "-meta" : "";
        std::string file = model_file_for_ratio(config_.models_dir, backbone, ratio, suffix);
        if (file.empty()) {
            std::string main =
                model_file_for_ratio(config_.models_dir, backbone, config_.main_ratio, suffix);
            if (!main.empty() && serves_ratio(main, ratio)) file = main;
        }
        if (file.empty()) return std::nullopt;
        return file;
    }

    /// Whether the checkpoint's backbone rebuilds at `ratio` (config_for_ratio), loaded once.
    bool serves_ratio(const std::string& file, int64_t ratio) const {
        auto key = std::make_pair(file, ratio);
        auto found = serves_ratio_.find(key);
        if (found == serves_ratio_.end())
            found = serves_ratio_
                        .emplace(key,
                                 !load_checkpoint(file).backbone->config_for_ratio(ratio).is_null())
                        .first;
        return found->second;
    }

    /// The cell of `spec`, evaluated or reused; a placeholder without results while another
    /// process holds its lock (deferred()).
    const RunResult& get(const RunSpec& spec) {
        std::string key = spec.directory();
        auto found = done_.find(key);
        if (found != done_.end()) return found->second;
        std::optional<RunResult> result = evaluate_or_reuse(key, spec);
        if (!result) {  // another process evaluates it: come back in a later pass
            ++deferred_;
            return deferred_result_;
        }
        return done_.emplace(key, std::move(*result)).first->second;
    }

  private:
    std::optional<RunResult> evaluate_or_reuse(const std::string& key, const RunSpec& spec) {
        RunResult result;
        result.dir = "runs/" + key;
        fs::path dir = out_dir_ / "runs" / key;
        fs::path cases = cases_dir(spec.set, spec.ratio);
        if (!fs::exists(cases / "cases.json")) {
            result.error = "no test cases at " + cases.string();
            return result;
        }
        int64_t max_cases = spec.max_cases >= 0 ? spec.max_cases : config_.max_cases;
        const nlohmann::json& identity = identity_of(key, spec, cases, max_cases);
        fs::path spec_file = dir / "spec.json";
        auto reusable = [&] {
            return fs::exists(dir / "cases.csv") && fs::exists(dir / "summary.json") &&
                   fs::exists(spec_file) &&
                   nlohmann::json::parse(std::ifstream(spec_file), nullptr, false) == identity;
        };
        // A cell that failed on its input (e.g. no sampling floor without a second GT sample)
        // fails again with the same identity: its error is kept, not retried or left pending.
        fs::path error_file = dir / "error.json";
        if (fs::exists(error_file)) {
            nlohmann::json failed =
                nlohmann::json::parse(std::ifstream(error_file), nullptr, false);
            if (failed.is_object() && failed.value("identity", nlohmann::json()) == identity) {
                result.error = failed.value("error", std::string("failed"));
                return result;
            }
        }
        if (!evaluate_ && !reusable()) {
            pending_.insert(key);
            result.error = "not evaluated yet";
            return result;
        }
        std::optional<CellLock> lock;
        if (!reusable()) {
            lock = CellLock::try_claim(fs::path(dir.string() + ".lock"));
            if (!lock) return std::nullopt;
        }
        ++count_;
        if (lock && !reusable()) {
            // spec.partial.json marks a cell begun with this identity: an interrupted
            // evaluation resumes after its last finished case.
            fs::path partial_spec = dir / "spec.partial.json";
            bool resume =
                fs::exists(partial_spec) &&
                nlohmann::json::parse(std::ifstream(partial_spec), nullptr, false) == identity;
            spdlog::info("reproduce: [{}] {} {}", count_, resume ? "resuming" : "evaluating", key);
            if (!resume) {
                fs::remove_all(dir);
                fs::create_directories(dir);
                std::ofstream(partial_spec) << identity.dump(2) << "\n";
            }
            EvalOptions options;
            options.resume = resume;
            options.method = spec.method;
            options.external_command = with_bindir(spec.command);
            options.noise = spec.noise;
            options.max_cases = max_cases;
            options.zero_shot.steps = spec.zero_shot.steps;
            options.zero_shot.batch_patches = spec.zero_shot.batch_patches;
            options.zero_shot.lr = spec.zero_shot.lr;
            options.save_first = config_.figure_cases;
            options.command_line = command_line_;
            InferenceModel model;
            if (spec.method == "zero-shot") model = load_inference_model(spec.model);
            if (spec.method == "network") {
                model = load_inference_model(spec.model, spec.ratio);
                set_adaptation(options.upsample, model, spec.tta_lr);
            }
            options.upsample.seed = config_.seed;
            options.upsample.tta_steps = spec.tta_steps;
            options.upsample.tta_unit = config_.tta_unit;
            try {
                evaluate_cases(cases.string(), model.backbone.get(), options, dir.string());
            } catch (const InputError& e) {
                // E.g. no sampling floor for sets without a second GT sample: a missing cell
                // (nothing to resume).
                fs::remove(partial_spec);
                result.error = e.what();
                std::ofstream(error_file)
                    << nlohmann::json{{"identity", identity}, {"error", result.error}}.dump(2)
                    << "\n";
                spdlog::warn("reproduce: {}: {}", key, result.error);
                return result;
            }
            fs::rename(partial_spec, spec_file);
        } else {
            spdlog::info("reproduce: [{}] reusing {}", count_, key);
        }
        result.summary = nlohmann::json::parse(std::ifstream(dir / "summary.json"));
        read_cases_csv(dir / "cases.csv", result);
        result.ok = true;
        return result;
    }

    /// What a cell's result depends on (its spec.json). Computed once per cell: it hashes or
    /// loads the model file, and a deferred cell is asked for again in every pass.
    const nlohmann::json& identity_of(const std::string& key, const RunSpec& spec,
                                      const fs::path& cases, int64_t max_cases) {
        auto found = identities_.find(key);
        if (found != identities_.end()) return found->second;
        nlohmann::json identity = {{"cases", cases.string()},
                                   {"method", spec.method},
                                   {"tta_steps", spec.tta_steps},
                                   {"tta_lr", spec.tta_lr},
                                   {"tta_unit", config_.tta_unit},
                                   {"noise", spec.noise},
                                   {"seed", config_.seed},
                                   {"max_cases", max_cases},
                                   {"figure_cases", config_.figure_cases}};
        if (spec.method == "network") identity["model_sha256"] = sha256_file(spec.model);
        // A zero-shot model starts fresh: only the architecture matters, not the weights.
        if (spec.method == "zero-shot") {
            nlohmann::json architecture = load_inference_model(spec.model).backbone->config();
            architecture.erase("seed");  // train_zero_shot sets its own
            identity["architecture"] = architecture;
            identity["zero_shot"] = {{"steps", spec.zero_shot.steps},
                                     {"batch_patches", spec.zero_shot.batch_patches},
                                     {"lr", spec.zero_shot.lr}};
        }
        if (spec.method == "external") identity["command"] = spec.command;
        return identities_.emplace(key, std::move(identity)).first->second;
    }

  public:
    /// Cells skipped in this pass because another process holds their lock; reset by
    /// start_pass().
    int64_t deferred() const { return deferred_; }
    void start_pass() { deferred_ = 0; }

  private:
    const ReproduceConfig& config_;
    fs::path out_dir_;
    std::string command_line_;
    bool evaluate_ = true;
    std::set<std::string> pending_;
    std::map<std::string, RunResult> done_;
    std::map<std::string, nlohmann::json> identities_;                      // by cell key
    mutable std::map<std::pair<std::string, int64_t>, bool> serves_ratio_;  // by (file, ratio)
    // ok = false: a placeholder cell until a later pass.
    RunResult deferred_result_{"", false, "being evaluated by another process", {}, {}, {}};
    int64_t count_ = 0;
    int64_t deferred_ = 0;
};

// ---------------------------------------------------------------------------------------------
// Tables.

struct Metric {
    std::string column, label;
    double scale;  // printed value = mean / scale
    bool higher_is_better;
};

const Metric kCd{"cd", "CD (×10⁻⁴)", 1e-4, false};
const Metric kHd{"hd", "HD (×10⁻²)", 1e-2, false};
const Metric kP2f{"p2f", "P2F (×10⁻³)", 1e-3, false};
const Metric kPsnr{"psnr", "PSNR (dB)", 1.0, true};
const Metric kSeconds{"seconds", "time (ms/object)", 1e-3, false};

std::string number(double v) {
    if (!std::isfinite(v)) return "—";
    return fmt::format("{:.{}f}", v, std::abs(v) >= 100 ? 1 : 3);
}

class TableWriter {
  public:
    explicit TableWriter(const ReproduceConfig& config) : config_(config) {}

    struct Row {
        std::string label;
        std::vector<const RunResult*> runs;   // one per column group
        std::vector<const RunResult*> bases;  // paired comparison per group (or null)
    };

    /// A markdown table: one column per (group, metric).
    void table(const std::string& table_id, const std::vector<std::string>& groups,
               const std::vector<Metric>& metrics, const std::vector<Row>& rows,
               nlohmann::json& json_table) {
        std::string header = "| method |", rule = "|---|";
        for (const std::string& group : groups)
            for (const Metric& m : metrics) {
                header += " " + (groups.size() > 1 ? group + " " : "") + m.label + " |";
                rule += "---|";
            }
        out_ << header << "\n" << rule << "\n";
        for (const Row& row : rows) {
            out_ << "| " << row.label << " |";
            nlohmann::json json_row = {{"label", row.label}, {"cells", nlohmann::json::array()}};
            for (size_t g = 0; g < groups.size(); ++g) {
                const RunResult* run = row.runs[g];
                const RunResult* base = g < row.bases.size() ? row.bases[g] : nullptr;
                for (const Metric& m : metrics) {
                    double value = run ? run->mean(m.column) : std::nan("");
                    std::string cell = number(value / m.scale);
                    nlohmann::json json_cell = {
                        {"group", groups[g]},
                        {"metric", m.column},
                        {"mean", std::isfinite(value) ? nlohmann::json(value) : nlohmann::json()}};
                    if (run) json_cell["run"] = run->dir;
                    if (run && !run->ok) json_cell["missing"] = run->error;
                    if (run && run->ok) json_cell["count"] = run->cases.size();
                    if (run && run->ok && base && base->ok && std::isfinite(value)) {
                        PairedComparison c = compare(*base, *run, m);
                        if (c.count > 0) {
                            cell += fmt::format(" ({:+.1f} %{})", 100 * c.relative_change,
                                                c.excludes_zero() ? "†" : "");
                            json_cell["vs_base"] = comparison_json(c);
                            details_.push_back(fmt::format(
                                "- {}, {}, {}: {} vs its base: n = {}, mean difference {:.4g} "
                                "(95 % CI [{:.4g}, {:.4g}]), better on {:.0f} % of objects",
                                table_id, groups[g], m.column, row.label, c.count,
                                c.mean_difference, c.ci_low, c.ci_high, 100 * c.fraction_improved));
                        }
                    }
                    out_ << " " << cell << " |";
                    json_row["cells"].push_back(json_cell);
                }
            }
            out_ << "\n";
            json_table["rows"].push_back(json_row);
        }
        out_ << "\n";
    }

    PairedComparison compare(const RunResult& base, const RunResult& run, const Metric& m) {
        // Pair by case name.
        std::map<std::string, double> base_scores;
        for (size_t i = 0; i < base.cases.size(); ++i)
            base_scores[base.cases[i]] = base.scores.at(m.column)[i];
        std::vector<double> a, b;
        for (size_t i = 0; i < run.cases.size(); ++i) {
            auto it = base_scores.find(run.cases[i]);
            if (it == base_scores.end()) continue;
            a.push_back(it->second);
            b.push_back(run.scores.at(m.column)[i]);
        }
        return compare_paired(a, b, m.higher_is_better, config_.bootstrap_resamples, 1);
    }

    static nlohmann::json comparison_json(const PairedComparison& c) {
        return {{"count", c.count},
                {"mean_difference", c.mean_difference},
                {"relative_change", c.relative_change},
                {"ci95", {c.ci_low, c.ci_high}},
                {"excludes_zero", c.excludes_zero()},
                {"fraction_improved", c.fraction_improved}};
    }

    std::ostringstream& out() { return out_; }
    std::vector<std::string>& details() { return details_; }

  private:
    const ReproduceConfig& config_;
    std::ostringstream out_;
    std::vector<std::string> details_;
};

std::string counts_line(Runner& runner, const std::vector<std::string>& sets, int64_t ratio,
                        const RunSpec& probe) {
    std::string text;
    for (const std::string& set : sets) {
        RunSpec spec = probe;
        spec.set = set;
        spec.ratio = ratio;
        const RunResult& r = runner.get(spec);
        text += fmt::format("{}{} ({})", text.empty() ? "" : ", ", set,
                            r.ok ? std::to_string(r.cases.size()) + " objects" : "no cases");
    }
    return text;
}

}  // namespace

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
    visit("external_baselines", c.external_baselines);
    visit("main_ratio", c.main_ratio);
    visit("table3_ratios", c.table3_ratios);
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
    return c;
}

nlohmann::json ReproduceConfig::to_json() const {
    nlohmann::json j = write_fields([&](auto&& visit) { reproduce_fields(*this, visit); });
    j["budget"] = budget;
    return j;
}

double ReproduceConfig::tta_lr_for(const std::string& backbone, int64_t ratio) const {
    for (const std::string& key : {backbone + "-x" + std::to_string(ratio), backbone}) {
        auto it = tta_lr_without_meta.find(key);
        if (it != tta_lr_without_meta.end()) return it->second;
    }
    return -1;
}

namespace {

/// One pass over every table: evaluates (or reuses) each cell through `runner` and returns
/// tables.json with the markdown under "markdown".
nlohmann::json tables_pass(const ReproduceConfig& config, Runner& runner,
                           const std::string& command_line) {
    TableWriter writer(config);
    std::ostringstream& md = writer.out();
    nlohmann::json tables = {{"config", config.to_json()},
                             {"command", command_line},
                             {"dataset_path", fs::absolute(config.dataset_dir).string()}};
    const int64_t r = config.main_ratio;
    const std::string n_label = "N = " + std::to_string(config.tta_steps);

    auto spec = [&](const std::string& set, int64_t ratio, const std::string& method) {
        RunSpec s;
        s.set = set;
        s.ratio = ratio;
        s.method = method;
        return s;
    };
    auto network_spec = [&](const std::string& set, int64_t ratio, const std::string& model,
                            int64_t steps, double lr = -1, const std::string& noise = "") {
        RunSpec s = spec(set, ratio, "network");
        s.model = model;
        s.tta_steps = steps;
        s.tta_lr = lr;
        s.noise = noise;
        return s;
    };
    auto network = [&](const std::string& set, int64_t ratio, const std::string& model,
                       int64_t steps, double lr = -1, const std::string& noise = "") {
        return &runner.get(network_spec(set, ratio, model, steps, lr, noise));
    };
    // One run per set of config.sets (the column groups of Tables I and IV).
    auto per_set = [&](const std::function<const RunResult*(const std::string&)>& run) {
        std::vector<const RunResult*> runs;
        for (const std::string& set : config.sets) runs.push_back(run(set));
        return runs;
    };
    std::vector<std::string> notes;
    auto models = [&](const std::string& backbone, int64_t ratio) {
        auto plain = runner.model_file(backbone, ratio, false);
        auto meta = runner.model_file(backbone, ratio, true);
        if (!plain)
            notes.push_back(fmt::format("{} at {}×: no model in {} (no rows)",
                                        display_name(backbone), ratio, config.models_dir));
        else if (!meta)
            notes.push_back(fmt::format("{} at {}×: no meta-trained model (no \"ours\" rows)",
                                        display_name(backbone), ratio));
        return std::make_pair(plain, meta);
    };

    md << "# pumeta: the paper's tables on this repository's data\n\n"
       << "Budget `" << config.budget << "`"
       << (config.max_cases > 0 ? fmt::format(" (first {} cases of each set)", config.max_cases)
                                : std::string(" (all cases)"))
       << ". Command: `" << command_line << "`.\n\n"
       << "Conventions (README, *Metrics*): every score is computed in the GT frame of each "
          "case (the normalised mesh's unit sphere); CD = mean of both directions' mean squared "
          "nearest distances; HD = max of both directions' max distance; P2F = mean distance "
          "of predicted points to the mesh surface; PSNR = pc_error D1 with the GT's bounding-"
          "box diagonal as peak. Each cell is a mean over objects. \"(±x %)\" is the change "
          "relative to the row's base (the plain backbone) on the same objects; † marks a "
          "paired difference whose 95 % bootstrap interval ("
       << config.bootstrap_resamples
       << " resamples of objects, seed 1) excludes 0. Test-time downsampler seed " << config.seed
       << "; adaptation unit `" << config.tta_unit << "`. \"TTA w/o meta\" = Algorithm 2 with "
       << "the merely pretrained model; \"ours\" = Algorithm 2 with the meta-trained model and its "
          "learned step sizes.\n\n";

    // ---- Table I --------------------------------------------------------------------------
    {
        md << "## Table I: " << r << "× on every test set\n\n"
           << "Data: " << counts_line(runner, config.sets, r, spec("", r, "input")) << ".\n\n";
        std::vector<TableWriter::Row> rows;
        auto reference_row = [&](const std::string& label, const std::string& method) {
            rows.push_back(
                {label,
                 per_set([&](const std::string& set) { return &runner.get(spec(set, r, method)); }),
                 {}});
        };
        reference_row("input, unchanged", "input");
        reference_row("sampling floor (2nd GT sample)", "floor");
        reference_row("midpoint baseline", "midpoint");
        for (const ExternalBaseline& baseline : config.external_baselines) {
            std::string command = with_bindir(baseline.command);
            std::string program = command.substr(0, command.find(' '));
            // A bare program name is left to the shell's PATH lookup.
            if (program.find('/') != std::string::npos && access(program.c_str(), X_OK) != 0) {
                notes.push_back(fmt::format("{}: {} is not built or not executable (no row)",
                                            baseline.label, program));
                continue;
            }
            rows.push_back({baseline.label,
                            per_set([&](const std::string& set) {
                                RunSpec s = spec(set, r, "external");
                                s.label = baseline.label;
                                // The template: a cell's identity does not depend on where
                                // this binary was run from.
                                s.command = baseline.command;
                                return &runner.get(s);
                            }),
                            {}});
        }
        for (const std::string& backbone : config.backbones) {
            const auto found = models(backbone, r);  // named: lambdas below use them
            const auto& plain = found.first;
            const auto& meta = found.second;
            if (!plain) continue;
            TableWriter::Row base{
                display_name(backbone),
                per_set([&](const std::string& set) { return network(set, r, *plain, 0); }),
                {}};
            rows.push_back(base);
            if (!meta) continue;
            rows.push_back({display_name(backbone) + " + ours (" + n_label + ")",
                            per_set([&](const std::string& set) {
                                return network(set, r, *meta, config.tta_steps);
                            }),
                            base.runs});
        }
        nlohmann::json& t1 = tables["table1"];
        writer.table("Table I", config.sets, {kCd, kPsnr}, rows, t1);
        md << "Extended (Hausdorff and point-to-surface distances):\n\n";
        nlohmann::json& t1x = tables["table1_extended"];
        writer.table("Table I (extended)", config.sets, {kHd, kP2f}, rows, t1x);
    }

    // ---- Table II -------------------------------------------------------------------------
    {
        const std::string set = config.sets.front();
        std::vector<std::string> levels = {"clean"};
        for (const std::string& n : config.noise) levels.push_back(n);
        const std::vector<std::string>& only = config.noise_backbones;
        md << "## Table II: noise robustness, " << r << "× on " << set << "\n\n"
           << "Inputs with Gaussian noise of the relative protocol (`relX` = X % of the GT's "
              "bounding-box diagonal, docs/data.md), scored against the clean GT.";
        const bool all_listed = std::all_of(
            config.backbones.begin(), config.backbones.end(),
            [&](const std::string& b) { return std::count(only.begin(), only.end(), b) > 0; });
        if (!only.empty() && !all_listed) {
            md << " Rows only for";
            for (const std::string& b : only) md << " " << display_name(b);
            md << " (`noise_backbones`: the others cost too much time here).";
        }
        md << "\n\n";
        std::vector<TableWriter::Row> rows;
        {
            TableWriter::Row row{"midpoint baseline", {}, {}};
            for (const std::string& level : levels) {
                RunSpec s = spec(set, r, "midpoint");
                s.noise = level == "clean" ? "" : level;
                row.runs.push_back(&runner.get(s));
            }
            rows.push_back(row);
        }
        for (const std::string& backbone : config.backbones) {
            if (!only.empty() && !std::count(only.begin(), only.end(), backbone)) continue;
            const auto found = models(backbone, r);  // named: lambdas below use them
            const auto& plain = found.first;
            const auto& meta = found.second;
            if (!plain) continue;
            TableWriter::Row base{display_name(backbone), {}, {}};
            for (const std::string& level : levels)
                base.runs.push_back(network(set, r, *plain, 0, -1, level == "clean" ? "" : level));
            rows.push_back(base);
            if (!meta) continue;
            TableWriter::Row ours{display_name(backbone) + " + ours", {}, base.runs};
            for (const std::string& level : levels)
                ours.runs.push_back(
                    network(set, r, *meta, config.tta_steps, -1, level == "clean" ? "" : level));
            rows.push_back(ours);
        }
        writer.table("Table II", levels, {kCd}, rows, tables["table2"]);
    }

    // ---- Table III ------------------------------------------------------------------------
    {
        const std::string set = config.sets.front();
        std::vector<std::string> groups;
        for (int64_t ratio : config.table3_ratios) groups.push_back(std::to_string(ratio) + "×");
        md << "## Table III: other ratios on " << set << "\n\n"
           << "A ratio without a native model uses a smaller-ratio model repeatedly (16× = 4× "
              "twice; adaptation then runs in each pass), or, for a backbone whose weights serve "
              "any ratio (PU-Dense keeps the rN likeliest voxels), the "
           << r
           << "× model with "
              "patches of (its patch size)·"
           << r << "/r input points.\n\n";
        std::vector<TableWriter::Row> rows;
        TableWriter::Row midpoint{"midpoint baseline", {}, {}};
        for (int64_t ratio : config.table3_ratios)
            midpoint.runs.push_back(&runner.get(spec(set, ratio, "midpoint")));
        rows.push_back(midpoint);
        for (const std::string& backbone : config.backbones) {
            TableWriter::Row base{display_name(backbone), {}, {}};
            TableWriter::Row ours{display_name(backbone) + " + ours", {}, {}};
            bool any_plain = false, any_meta = false;
            for (int64_t ratio : config.table3_ratios) {
                auto [plain, meta] = models(backbone, ratio);
                base.runs.push_back(plain ? network(set, ratio, *plain, 0) : nullptr);
                ours.runs.push_back(meta ? network(set, ratio, *meta, config.tta_steps) : nullptr);
                any_plain |= bool(plain);
                any_meta |= bool(meta);
            }
            ours.bases = base.runs;
            if (any_plain) rows.push_back(base);
            if (any_meta) rows.push_back(ours);
        }
        writer.table("Table III", groups, {kCd, kPsnr}, rows, tables["table3"]);
    }

    // ---- Table IV -------------------------------------------------------------------------
    {
        md << "## Table IV: ablation, " << r << "× (" << n_label << ")\n\n"
           << "\"ours, no adaptation\" is the meta-trained model used without adaptation: it "
              "separates what meta-training changed in the weights from what adaptation adds.\n\n";
        std::vector<TableWriter::Row> rows;
        for (const std::string& backbone : config.backbones) {
            const auto found = models(backbone, r);  // named: lambdas below use them
            const auto& plain = found.first;
            const auto& meta = found.second;
            if (!plain) continue;
            TableWriter::Row base{
                display_name(backbone),
                per_set([&](const std::string& set) { return network(set, r, *plain, 0); }),
                {}};
            rows.push_back(base);
            double lr = config.tta_lr_for(backbone, r);
            TableWriter::Row tta{display_name(backbone) + " + TTA w/o meta",
                                 per_set([&](const std::string& set) {
                                     return network(set, r, *plain, config.tta_steps, lr);
                                 }),
                                 base.runs};
            rows.push_back(tta);
            if (!meta) continue;
            std::vector<const RunResult*> ours = per_set(
                [&](const std::string& set) { return network(set, r, *meta, config.tta_steps); });
            rows.push_back(
                {display_name(backbone) + " + ours, no adaptation",
                 per_set([&](const std::string& set) { return network(set, r, *meta, 0); }),
                 base.runs});
            rows.push_back({display_name(backbone) + " + ours", ours, base.runs});
            rows.push_back({display_name(backbone) + " + ours vs TTA w/o meta", ours, tta.runs});
        }
        writer.table("Table IV", config.sets, {kCd, kPsnr}, rows, tables["table4"]);
        md << "The last row of each backbone repeats \"ours\" with \"TTA w/o meta\" as its base "
              "(equal N).\n\n";
    }

    // ---- Table V --------------------------------------------------------------------------
    {
        const std::string set = config.sets.front();
        md << "## Table V: number of adaptation steps, " << r << "× on " << set << "\n\n"
           << "Time is the wall time per object on this machine (mean), adaptation included; "
              "the first row of each backbone is the plain backbone.\n\n";
        std::vector<TableWriter::Row> rows;
        for (const std::string& backbone : config.sweep_backbones) {
            const auto found = models(backbone, r);  // named: lambdas below use them
            const auto& plain = found.first;
            const auto& meta = found.second;
            if (!plain || !meta) continue;
            TableWriter::Row base{
                display_name(backbone) + ", plain", {network(set, r, *plain, 0)}, {}};
            rows.push_back(base);
            for (int64_t steps : config.steps_sweep)
                rows.push_back({display_name(backbone) + " + ours, N = " + std::to_string(steps),
                                {network(set, r, *meta, steps)},
                                base.runs});
        }
        writer.table("Table V", {set}, {kCd, kPsnr, kSeconds}, rows, tables["table5"]);
    }

    // ---- Table VI (beyond the paper) -----------------------------------------------------
    if (config.zero_shot.max_cases > 0) {
        const ZeroShotBaseline& z = config.zero_shot;
        md << "## Table VI: internal learning vs external pretraining, " << r << "× (first "
           << z.max_cases << " objects of each set)\n\n"
           << "\"zero-shot\" trains the backbone from a fresh initialisation on each input's own "
              "pairs (X↓, X) only, in the spirit of ZSPU: "
           << z.steps << " Adam steps of " << z.batch_patches << " patches, lr " << z.lr
           << ", random rotations; its time per object includes that training. Its base is the "
              "pretrained backbone on the same objects, so the change shows what external "
              "pretraining buys.";
        if (!z.backbones.empty()) {
            md << " Zero-shot rows only for";
            for (const std::string& b : z.backbones) md << " " << display_name(b);
            md << " (`zero_shot.backbones`: the others cost too much time here).";
        }
        md << "\n\n";
        auto first = [&](RunSpec s) {
            s.max_cases = z.max_cases;
            return &runner.get(s);
        };
        std::vector<TableWriter::Row> rows;
        rows.push_back(
            {"midpoint baseline",
             per_set([&](const std::string& set) { return first(spec(set, r, "midpoint")); }),
             {}});
        for (const std::string& backbone : config.backbones) {
            const auto found = models(backbone, r);  // named: lambdas below use them
            const auto& plain = found.first;
            const auto& meta = found.second;
            if (!plain) continue;
            TableWriter::Row base{display_name(backbone),
                                  per_set([&](const std::string& set) {
                                      return first(network_spec(set, r, *plain, 0));
                                  }),
                                  {}};
            const std::vector<std::string>& only = z.backbones;
            if (only.empty() || std::count(only.begin(), only.end(), backbone))
                rows.push_back({display_name(backbone) + " zero-shot (from scratch)",
                                per_set([&](const std::string& set) {
                                    RunSpec s = spec(set, r, "zero-shot");
                                    s.model = *plain;
                                    s.zero_shot = z;
                                    return first(s);
                                }),
                                base.runs});
            rows.push_back(base);
            if (!meta) continue;
            rows.push_back({display_name(backbone) + " + ours (" + n_label + ")",
                            per_set([&](const std::string& set) {
                                return first(network_spec(set, r, *meta, config.tta_steps));
                            }),
                            base.runs});
        }
        writer.table("Table VI", config.sets, {kCd, kPsnr, kSeconds}, rows, tables["table6"]);
    }

    for (const std::string& cell : runner.pending())
        notes.push_back("not evaluated yet (`--tables-only`): runs/" + cell);
    if (!notes.empty()) {
        std::sort(notes.begin(), notes.end());
        notes.erase(std::unique(notes.begin(), notes.end()), notes.end());
        md << "## Missing rows\n\n";
        for (const std::string& note : notes) md << "- " << note << "\n";
        md << "\n";
        tables["missing"] = notes;
    }
    md << "## Paired comparisons\n\n";
    for (const std::string& line : writer.details()) md << line << "\n";
    tables["markdown"] = md.str();
    return tables;
}

}  // namespace

nlohmann::json reproduce(const ReproduceConfig& config, const std::string& out_dir,
                         const std::string& command_line, bool evaluate) {
    fs::create_directories(out_dir);
    Runner runner(config, out_dir, command_line, evaluate);
    for (;;) {
        runner.start_pass();
        nlohmann::json tables = tables_pass(config, runner, command_line);
        if (runner.deferred() == 0) {
            io::write_atomically((fs::path(out_dir) / "tables.md").string(),
                                 tables["markdown"].get<std::string>());
            io::write_atomically((fs::path(out_dir) / "tables.json").string(),
                                 tables.dump(2) + "\n");
            return tables;
        }
        // Another `pumeta reproduce` on the same output evaluates these cells.
        spdlog::info("reproduce: waiting for {} cells that another process is evaluating",
                     runner.deferred());
        std::this_thread::sleep_for(std::chrono::seconds(3));
    }
}

}  // namespace pumeta
