// Loading a model for inference: a pretrained or meta-trained checkpoint, with the adaptation
// defaults a meta-trained one carries, and the choice of the model that serves a ratio.
#pragma once

#include <memory>
#include <nlohmann/json.hpp>
#include <string>

#include "pumeta/inference/adaptation.h"
#include "pumeta/models/backbone.h"

namespace pumeta {

struct InferenceModel {
    std::unique_ptr<Backbone> backbone;
    /// Meta-trained: its file stores the inner-loop settings it was meta-trained with.
    bool meta_trained = false;
    /// The file's adaptation defaults (stored_adaptation(): none for a plain model).
    Adaptation adaptation;
    nlohmann::json extra;
};

/// Loads a checkpoint. With ratio > 0 and a backbone whose weights serve any ratio
/// (Backbone::config_for_ratio, e.g. PU-Dense) the network is rebuilt for that ratio; other
/// backbones keep their own ratio (the pipeline applies them repeatedly or names the problem).
InferenceModel load_inference_model(const std::string& path, int64_t ratio = 0);

/// The output ratio when neither the user nor a model file says: the shipped default model's.
inline constexpr int64_t kDefaultRatio = 4;

/// A model and the output ratio it serves.
struct ServedModel {
    InferenceModel model;
    int64_t ratio = 0;
    /// The file it was loaded from.
    std::string path;
};

/// The one place that decides which model serves which output ratio: `path`, or when empty the
/// shipped default model for `ratio` (default_model_for_ratio); `ratio` 0 means the model's own.
/// The model is rebuilt at the ratio when its weights serve any ratio; otherwise the ratio must be
/// a power of the model's (applied repeatedly), else an InputError naming both.
ServedModel serve(const std::string& path, int64_t ratio);

/// The directory of the shipped models: $PUMETA_MODELS if set, else share/pumeta/models beside
/// the running program's bin/ (an installed or unpacked package), else the installed models
/// (<install prefix>/share/pumeta/models), each only when it holds defaults.json, else the
/// source tree's models/. A library installed elsewhere than its configured prefix, in a
/// program outside that prefix, needs $PUMETA_MODELS.
std::string models_dir();

/// The family of the shipped default models: "family" of models_dir()/defaults.json
/// (InputError naming the file when it is missing or malformed).
std::string default_model_family();

/// The shipped model for an output ratio (0 = the default kDefaultRatio):
/// <family>-x<ratio>.pt when it exists, else the model of the largest shipped ratio b with
/// ratio a power of b (16: the 4× model twice), else <family>-x4.pt (whose ratio check then
/// names the problem).
std::string default_model_for_ratio(int64_t ratio);

/// The model file for an output ratio in `dir`: <name>-x<ratio><suffix>.pt when it exists,
/// else <name>-x<b><suffix>.pt for the largest b in {8, 4, 2} with ratio a power of b (the
/// pipeline applies it repeatedly). Empty when none exists.
std::string model_file_for_ratio(const std::string& dir, const std::string& name, int64_t ratio,
                                 const std::string& suffix = "");

}  // namespace pumeta
