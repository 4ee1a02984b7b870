#include "pumeta/eval/cell_cache.h"

#include <fcntl.h>
#include <fmt/format.h>
#include <spdlog/spdlog.h>
#include <unistd.h>

#include <cctype>
#include <cerrno>
#include <cmath>
#include <csignal>
#include <fstream>

#include "pumeta/core/error.h"
#include "pumeta/core/sha256.h"
#include "pumeta/data/layout.h"
#include "pumeta/eval/benchmark_protocol.h"
#include "pumeta/eval/cases_csv.h"
#include "pumeta/eval/evaluate_benchmark.h"
#include "pumeta/eval/evaluate_cases.h"
#include "pumeta/inference/model_file.h"
#include "pumeta/inference/upsample.h"

namespace pumeta {

namespace fs = std::filesystem;

namespace {

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

}  // namespace

std::string RunSpec::directory() const {
    std::string name = method == "network" ? fs::path(model).stem().string() : method;
    if (method == "zero-shot")
        name = fmt::format("zero-shot-{}.s{}", fs::path(model).stem().string(), zero_shot.steps);
    if (method == "external") {
        name = "external-";
        for (char c : label)
            name += std::isalnum(static_cast<unsigned char>(c)) ? char(std::tolower(c)) : '-';
    }
    if (method == "network") name += tta_steps > 0 ? ".tta" + std::to_string(tta_steps) : "";
    if (tta_lr) name += fmt::format(".lr{:g}", *tta_lr);
    if (max_cases >= 0) name += fmt::format(".first{}", max_cases);
    std::string cases = set + "-x" + std::to_string(ratio) + (noise.empty() ? "" : "-" + noise);
    return cases + "/" + name;
}

double RunResult::mean(const std::string& column) const {
    if (!ok || !scores.count(column)) return std::nan("");
    double sum = 0;
    int64_t n = 0;
    for (double v : scores.at(column))
        if (std::isfinite(v)) sum += v, ++n;
    return n ? sum / n : std::nan("");
}

CellCache::CellCache(const ReproduceConfig& config, fs::path out_dir, std::string command_line,
                     bool evaluate)
    : config_(config),
      out_dir_(std::move(out_dir)),
      command_line_(std::move(command_line)),
      evaluate_(evaluate) {}

const RunResult& CellCache::get(const RunSpec& spec) {
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

std::optional<RunResult> CellCache::evaluate_or_reuse(const std::string& key, const RunSpec& spec) {
    RunResult result;
    result.dir = "runs/" + key;
    fs::path dir = out_dir_ / "runs" / key;
    fs::path cases;
    std::optional<BenchmarkLayout> benchmark;
    if (const PublicBenchmark* public_benchmark = config_.benchmark(spec.set)) {
        try {
            benchmark = find_benchmark_layout(public_benchmark->data_dir,
                                              public_benchmark->input_points, spec.ratio);
        } catch (const InputError& e) {
            result.error = e.what();
            return result;
        }
        benchmark->benchmark = public_benchmark->name;
        cases = public_benchmark->data_dir;
    } else {
        cases = layout::cases_dir(config_.dataset_dir, spec.set, spec.ratio);
        if (!fs::exists(layout::case_index_path(cases))) {
            result.error = "no test cases at " + cases.string();
            return result;
        }
    }
    int64_t max_cases = spec.max_cases >= 0 ? spec.max_cases : config_.max_cases;
    const nlohmann::json& identity =
        identity_of(key, spec, cases, max_cases, benchmark ? &*benchmark : nullptr);
    fs::path spec_file = dir / "spec.json";
    auto reusable = [&] {
        return fs::exists(dir / kCasesCsvFile) && fs::exists(dir / "summary.json") &&
               fs::exists(spec_file) &&
               nlohmann::json::parse(std::ifstream(spec_file), nullptr, false) == identity;
    };
    // A cell that failed on its input (e.g. no sampling floor without a second GT sample)
    // fails again with the same identity: its error is kept, not retried or left pending.
    fs::path error_file = dir / "error.json";
    if (fs::exists(error_file)) {
        nlohmann::json failed = nlohmann::json::parse(std::ifstream(error_file), nullptr, false);
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
        if (!evaluate(key, spec, dir, cases, max_cases, identity, benchmark ? &*benchmark : nullptr,
                      result))
            return result;
    } else {
        spdlog::info("reproduce: [{}] reusing {}", count_, key);
    }
    result.summary = nlohmann::json::parse(std::ifstream(dir / "summary.json"));
    CaseScores scores = read_cases_csv((dir / kCasesCsvFile).string());
    result.cases = std::move(scores.cases);
    result.scores = std::move(scores.scores);
    result.ok = true;
    return result;
}

bool CellCache::evaluate(const std::string& key, const RunSpec& spec, const fs::path& dir,
                         const fs::path& cases, int64_t max_cases, const nlohmann::json& identity,
                         const BenchmarkLayout* benchmark, RunResult& result) {
    // spec.partial.json marks a cell begun with this identity: an interrupted
    // evaluation resumes after its last finished case.
    fs::path partial_spec = dir / "spec.partial.json";
    bool resume = fs::exists(partial_spec) &&
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
        model = std::move(serve(spec.model, spec.ratio).model);
        AdaptationOverrides overrides;
        overrides.steps = spec.tta_steps;
        overrides.step_size = spec.tta_lr;
        overrides.unit = parse_adaptation_unit(config_.tta_unit, "reproduce config: tta_unit");
        options.upsample.adaptation =
            adaptation_for(model.adaptation, model.meta_trained, overrides);
    }
    options.upsample.seed = config_.seed;
    try {
        if (benchmark)
            evaluate_benchmark(*benchmark, model.backbone.get(), options, dir.string());
        else
            evaluate_cases(cases.string(), model.backbone.get(), options, dir.string());
    } catch (const InputError& e) {
        // E.g. no sampling floor for sets without a second GT sample: a missing cell
        // (nothing to resume).
        fs::remove(partial_spec);
        result.error = e.what();
        std::ofstream(dir / "error.json")
            << nlohmann::json{{"identity", identity}, {"error", result.error}}.dump(2) << "\n";
        spdlog::warn("reproduce: {}: {}", key, result.error);
        return false;
    }
    fs::rename(partial_spec, dir / "spec.json");
    return true;
}

/// What a cell's result depends on (its spec.json). Computed once per cell: it hashes or
/// loads the model file, and a deferred cell is asked for again in every pass.
const nlohmann::json& CellCache::identity_of(const std::string& key, const RunSpec& spec,
                                             const fs::path& cases, int64_t max_cases,
                                             const BenchmarkLayout* benchmark) {
    auto found = identities_.find(key);
    if (found != identities_.end()) return found->second;
    nlohmann::json identity = {{"cases", cases.string()},
                               {"method", spec.method},
                               {"tta_steps", spec.tta_steps},
                               // -1 for the model's own step sizes: the form cells
                               // evaluated before keep in their spec.json.
                               {"tta_lr", spec.tta_lr.value_or(-1.0)},
                               {"tta_unit", config_.tta_unit},
                               {"noise", spec.noise},
                               {"seed", config_.seed},
                               {"max_cases", max_cases},
                               {"figure_cases", config_.figure_cases}};
    if (spec.method == "network") identity["model_sha256"] = sha256_file(spec.model);
    if (spec.method == "network" || spec.method == "zero-shot")
        identity["pipeline"] = kPipelineVersion;
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
    if (benchmark) {
        // Its objects by name: a mesh added to or removed from the folder makes a new cell.
        nlohmann::json objects = nlohmann::json::array();
        for (const BenchmarkObject& object : benchmark->objects) objects.push_back(object.name);
        identity["benchmark"] = {{"input_dir", benchmark->input_dir},
                                 {"gt_dir", benchmark->gt_dir},
                                 {"objects", objects},
                                 {"protocol", benchmark_protocol_description()}};
    }
    return identities_.emplace(key, std::move(identity)).first->second;
}

}  // namespace pumeta
