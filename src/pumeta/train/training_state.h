// Everything a training or meta-training run needs to resume exactly: the model, the
// optimiser's tensors and a JSON of counters, in one checkpoint container (save_tensors).
#pragma once

#include <functional>
#include <memory>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "pumeta/models/backbone.h"
#include "pumeta/nn/parameters.h"

namespace pumeta {

/// An exclusive lock on a run directory (flock on run_dir/lock), held while it lives, so that
/// two trainers never write one run at once.
class RunLock {
  public:
    /// InputError naming the directory (and the holder's pid) when another process holds it.
    explicit RunLock(const std::string& run_dir);
    ~RunLock();
    RunLock(const RunLock&) = delete;
    RunLock& operator=(const RunLock&) = delete;

  private:
    int fd_ = -1;
};

struct TrainingState {
    std::unique_ptr<Backbone> model;
    ParamMap optimizer;
    nlohmann::json info;
    std::shared_ptr<RunLock> lock;  ///< held by the writing rank for the whole run
};

/// The key under which a run's state stores its config, compared on resume.
inline constexpr char kRunConfigKey[] = "run_config";

/// The config as a run records and compares it: without the "distributed" section and
/// "run_dir", which may differ between the processes or sessions of one run.
nlohmann::json comparable_config(nlohmann::json config);

/// The fields ("a.b" paths) in which `now` differs from `stored`; fields that only one of them
/// has (written before they existed, or retired since) do not count.
std::vector<std::string> changed_fields(const nlohmann::json& stored, const nlohmann::json& now);

/// The fields ("a.b" paths) that `now` has and `stored` lacks: settings added to the code
/// after the stored run began. A resume takes them at `now`'s values and says so.
std::vector<std::string> added_fields(const nlohmann::json& stored, const nlohmann::json& now);

/// Appends one JSON record as a line of `file`.
void append_log(const std::string& file, const nlohmann::json& record);

/// Drops the records of `file` with a "step" above `step` (written after the checkpoint that
/// a resumed run continues from, and about to be written again).
void truncate_log(const std::string& file, int64_t step);

/// Written atomically; model tensors under "model/", optimiser tensors under "optim/".
void save_training_state(const std::string& path, const Backbone& model, const ParamMap& optimizer,
                         const nlohmann::json& info);

/// Rebuilds the model from the stored config; InputError for a corrupted or foreign file.
TrainingState load_training_state(const std::string& path);

/// How a run starts: from scratch, or resuming with the named config fields allowed to differ
/// from the stored run's ("steps", "meta.inner_lr"; a name also allows every field under it).
struct RunStart {
    bool resume = false;
    std::vector<std::string> allow_changes;
};

/// The start of a (meta-)training run in `run_dir`: with `resume` and a run_dir/state.ckpt,
/// that state (info["step"] says where), refused when `config` (comparable_config) differs
/// from the stored one in a field not allowed, the changes logged, and log.jsonl cut back to
/// the state's step; otherwise a fresh model from `make_fresh` with empty info, and (when
/// `writes`, i.e. on rank 0) the directory created and an old log.jsonl removed. The writing
/// rank locks the directory first. `what` names the command in log lines ("train",
/// "meta-train").
TrainingState open_run(const std::string& run_dir, const RunStart& start, bool writes,
                       const std::string& what, const nlohmann::json& config,
                       const std::function<std::unique_ptr<Backbone>()>& make_fresh);

}  // namespace pumeta
