// Which checkpoint in a reproduction's models directory serves a backbone at a ratio.
#pragma once

#include <cstdint>
#include <map>
#include <optional>
#include <string>
#include <utility>

namespace pumeta {

/// Looks up model files by the backbone names of the config; checkpoints are loaded at most
/// once per (file, ratio) across the passes of a reproduction.
class ModelFiles {
  public:
    ModelFiles(std::string models_dir, int64_t main_ratio)
        : models_dir_(std::move(models_dir)), main_ratio_(main_ratio) {}

    /// The checkpoint of a backbone at a ratio: <bb>-x<r>[-meta].pt, else a model of a smaller
    /// ratio that the pipeline can apply repeatedly (16× = 4× twice), else the main ratio's
    /// model when its weights serve any ratio (PU-Dense; load_inference_model rebuilds it),
    /// else <bb>[-meta].pt when it serves the ratio (MPU's 2×-16×, Meta-PU's 2×-16×).
    std::optional<std::string> find(const std::string& backbone, int64_t ratio, bool meta) const;

  private:
    /// Whether the checkpoint's backbone is at `ratio` or rebuilds there (config_for_ratio),
    /// loaded once.
    bool serves_ratio(const std::string& file, int64_t ratio) const;

    std::string models_dir_;
    int64_t main_ratio_;
    mutable std::map<std::pair<std::string, int64_t>, bool> serves_ratio_;  // by (file, ratio)
};

}  // namespace pumeta
