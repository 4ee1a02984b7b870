#include "pumeta/train/training_state.h"

#include <ATen/ATen.h>
#include <fcntl.h>
#include <spdlog/spdlog.h>
#include <sys/file.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <filesystem>
#include <fstream>

#include "pumeta/core/error.h"
#include "pumeta/geometry/io/file.h"
#include "pumeta/models/checkpoint.h"

namespace pumeta {

namespace {
const std::string kModel = "model/";
const std::string kOptim = "optim/";
const std::string kBuffers = "buffers/";
}  // namespace

void save_training_state(const std::string& path, const Backbone& model, const ParamMap& optimizer,
                         const nlohmann::json& info) {
    ParamMap tensors;
    for (const auto& [name, p] : model.parameters()) tensors[kModel + name] = p.detach();
    for (const auto& [name, b] : model.buffers()) tensors[kBuffers + name] = b;
    for (const auto& [name, t] : optimizer) tensors[kOptim + name] = t.detach();
    save_tensors(path, tensors,
                 {{"kind", "training_state"}, {"backbone", model.config()}, {"info", info}});
}

TrainingState load_training_state(const std::string& path) {
    TensorFile file = load_tensors(path);
    if (file.extra.value("kind", "") != "training_state")
        throw_input_error(path, "not a training state file");
    TrainingState state;
    int64_t model_elements = 0;
    for (const auto& [name, tensor] : file.tensors)
        if (name.rfind(kModel, 0) == 0 || name.rfind(kBuffers, 0) == 0)
            model_elements += tensor.numel();
    {
        ParameterBudget budget(2 * model_elements + (1 << 20), path);  // as load_checkpoint
        state.model = make_backbone(file.extra.at("backbone"));
    }
    state.info = file.extra.at("info");
    for (auto& [name, p] : state.model->parameters()) {
        auto it = file.tensors.find(kModel + name);
        if (it == file.tensors.end())
            throw_input_error(path, "training state lacks parameter '{}'", name);
        if (!it->second.sizes().equals(p.sizes()))
            throw_input_error(path, "parameter '{}' has shape {} in the file", name,
                              fmt::format("{}", fmt::join(it->second.sizes(), "x")));
        at::NoGradGuard no_grad;
        p.copy_(it->second);
    }
    for (auto& [name, b] : state.model->buffers()) {
        auto it = file.tensors.find(kBuffers + name);
        if (it == file.tensors.end())
            throw_input_error(path, "training state lacks buffer '{}'", name);
        if (!it->second.sizes().equals(b.sizes()))
            throw_input_error(path, "buffer '{}' has shape {} in the file", name,
                              fmt::format("{}", fmt::join(it->second.sizes(), "x")));
        b = it->second.to(b.scalar_type());
    }
    for (auto& [name, t] : file.tensors)
        if (name.rfind(kOptim, 0) == 0) state.optimizer[name.substr(kOptim.size())] = t;
    return state;
}

RunLock::RunLock(const std::string& run_dir) {
    const std::string file = (std::filesystem::path(run_dir) / "lock").string();
    fd_ = ::open(file.c_str(), O_RDWR | O_CREAT | O_CLOEXEC, 0644);
    if (fd_ < 0) throw_input_error(run_dir, "cannot create the run lock: {}", std::strerror(errno));
    if (::flock(fd_, LOCK_EX | LOCK_NB) != 0) {
        char holder[32] = {};
        const ssize_t got = ::pread(fd_, holder, sizeof(holder) - 1, 0);
        ::close(fd_);
        throw_input_error(run_dir,
                          "another trainer{} is writing this run directory; wait for it or "
                          "stop it",
                          got > 0 ? fmt::format(" (pid {})", std::string(holder, got)) : "");
    }
    const std::string pid = std::to_string(::getpid());
    if (::ftruncate(fd_, 0) != 0 || ::pwrite(fd_, pid.data(), pid.size(), 0) < 0)
        spdlog::debug("{}: could not record the pid in the run lock", run_dir);
}

RunLock::~RunLock() {
    if (fd_ >= 0) ::close(fd_);  // releases the flock
}

nlohmann::json comparable_config(nlohmann::json config) {
    if (config.is_object()) {
        config.erase("distributed");
        config.erase("run_dir");
    }
    return config;
}

namespace {

/// One walk over `now`'s fields: those whose value differs from `stored`'s into `changes`,
/// those `stored` lacks into `added`.
void collect_changes(const nlohmann::json& stored, const nlohmann::json& now,
                     const std::string& prefix, std::vector<std::string>& changes,
                     std::vector<std::string>& added) {
    if (stored.is_object() && now.is_object()) {
        for (const auto& [key, value] : now.items()) {
            const std::string path = prefix.empty() ? key : prefix + "." + key;
            if (!stored.contains(key))
                added.push_back(path);
            else
                collect_changes(stored[key], value, path, changes, added);
        }
        // Keys `now` lacks are settings this version no longer has (now lists every field it
        // knows): retired, not changed.
        return;
    }
    // Numbers compare by value: 1 and 1.0 are the same setting.
    if (stored.is_number() && now.is_number()) {
        if (stored.get<double>() != now.get<double>()) changes.push_back(prefix);
        return;
    }
    if (stored != now) changes.push_back(prefix);
}

bool allowed(const std::string& field, const std::vector<std::string>& allow) {
    for (const std::string& name : allow)
        if (field == name || field.rfind(name + ".", 0) == 0) return true;
    return false;
}

const nlohmann::json* field_at(const nlohmann::json& config, const std::string& path) {
    const nlohmann::json* node = &config;
    size_t begin = 0;
    while (begin <= path.size()) {
        const size_t end = std::min(path.find('.', begin), path.size());
        const std::string key = path.substr(begin, end - begin);
        if (!node->is_object() || !node->contains(key)) return nullptr;
        node = &(*node)[key];
        begin = end + 1;
    }
    return node;
}

std::string field_text(const nlohmann::json& config, const std::string& path) {
    const nlohmann::json* value = field_at(config, path);
    return value ? value->dump() : "(absent)";
}

}  // namespace

std::vector<std::string> changed_fields(const nlohmann::json& stored, const nlohmann::json& now) {
    std::vector<std::string> changes, added;
    collect_changes(stored, now, "", changes, added);
    return changes;
}

std::vector<std::string> added_fields(const nlohmann::json& stored, const nlohmann::json& now) {
    std::vector<std::string> changes, added;
    collect_changes(stored, now, "", changes, added);
    return added;
}

void append_log(const std::string& file, const nlohmann::json& record) {
    std::ofstream(file, std::ios::app) << record.dump() << "\n";
}

void truncate_log(const std::string& file, int64_t step) {
    std::ifstream in(file);
    if (!in) return;
    std::string kept, line;
    int64_t dropped = 0;
    while (std::getline(in, line)) {
        const nlohmann::json record = nlohmann::json::parse(line, nullptr, false);
        // A line cut short by a kill is dropped with the records after the checkpoint.
        if (record.is_discarded() || (record.contains("step") && record["step"].is_number() &&
                                      record["step"].get<int64_t>() > step)) {
            ++dropped;
            continue;
        }
        kept += line + "\n";
    }
    in.close();
    if (dropped == 0) return;
    io::write_atomically(file, kept);
    spdlog::info("{}: dropped {} records after step {}, which the resumed run writes again", file,
                 dropped, step);
}

TrainingState open_run(const std::string& run_dir, const RunStart& start, bool writes,
                       const std::string& what, const nlohmann::json& config,
                       const std::function<std::unique_ptr<Backbone>()>& make_fresh) {
    namespace fs = std::filesystem;
    std::shared_ptr<RunLock> lock;
    if (writes) {
        fs::create_directories(run_dir);
        lock = std::make_shared<RunLock>(run_dir);
    }
    const fs::path state_file = fs::path(run_dir) / "state.ckpt";
    const nlohmann::json now = comparable_config(config);
    if (start.resume && fs::exists(state_file)) {
        TrainingState state = load_training_state(state_file.string());
        state.lock = lock;
        const int64_t step = state.info.value("step", int64_t{0});
        // States written before the key existed kept the supervised config as "train_config".
        const nlohmann::json stored = comparable_config(
            state.info.value(kRunConfigKey, state.info.value("train_config", nlohmann::json())));
        if (stored.is_null()) {
            if (writes)
                spdlog::warn("{}: the state in {} records no config; changes cannot be checked",
                             what, run_dir);
        } else {
            std::vector<std::string> refused, accepted;
            for (const std::string& field : changed_fields(stored, now))
                (allowed(field, start.allow_changes) ? accepted : refused).push_back(field);
            if (!refused.empty()) {
                std::string list;
                for (const std::string& field : refused)
                    list += fmt::format("{}{} ({} -> {})", list.empty() ? "" : ", ", field,
                                        field_text(stored, field), field_text(now, field));
                throw_input_error(run_dir,
                                  "--resume with a changed config: {}; resume with the run's "
                                  "config, or allow named fields with --allow-change",
                                  list);
            }
            if (writes) {
                for (const std::string& field : accepted)
                    spdlog::info("{}: resuming with {} changed from {} to {}", what, field,
                                 field_text(stored, field), field_text(now, field));
                for (const std::string& field : added_fields(stored, now))
                    spdlog::info("{}: resuming with {} = {} (the run predates the field)", what,
                                 field, field_text(now, field));
            }
        }
        if (writes) {
            truncate_log((fs::path(run_dir) / "log.jsonl").string(), step);
            spdlog::info("{}: resuming {} at step {}", what, run_dir, step);
        }
        return state;
    }
    if (start.resume && writes)
        spdlog::warn("{}: no state in {}; starting from scratch", what, run_dir);
    TrainingState fresh;
    fresh.model = make_fresh();
    fresh.lock = lock;
    if (writes) fs::remove(fs::path(run_dir) / "log.jsonl");
    return fresh;
}

}  // namespace pumeta
