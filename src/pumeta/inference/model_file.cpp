#include "pumeta/inference/model_file.h"

#include <ATen/ATen.h>

#include <cstdlib>
#include <filesystem>

#include "pumeta/inference/upsample.h"
#include "pumeta/models/checkpoint.h"

namespace pumeta {

namespace {

/// `backbone` rebuilt for `ratio` with the same parameters and buffers, when its weights serve
/// that ratio; else `backbone` itself.
std::unique_ptr<Backbone> at_ratio(std::unique_ptr<Backbone> backbone, int64_t ratio) {
    if (ratio <= 0 || ratio == backbone->ratio()) return backbone;
    nlohmann::json config = backbone->config_for_ratio(ratio);
    if (config.is_null()) return backbone;
    std::unique_ptr<Backbone> rebuilt = make_backbone(config);
    at::NoGradGuard no_grad;
    auto copy = [](ParamMap& to, const ParamMap& from) {
        for (auto& [name, tensor] : to) tensor.copy_(param(from, name));
    };
    copy(rebuilt->parameters(), backbone->parameters());
    copy(rebuilt->buffers(), backbone->buffers());
    return rebuilt;
}

}  // namespace

InferenceModel load_inference_model(const std::string& path, int64_t ratio) {
    LoadedCheckpoint checkpoint = load_checkpoint(path);
    InferenceModel model;
    model.backbone = at_ratio(std::move(checkpoint.backbone), ratio);
    model.extra = checkpoint.extra;
    const bool has = model.extra.is_object() && model.extra.contains("meta");
    model.meta_trained = has;
    model.adaptation = stored_adaptation(
        has ? model.extra["meta"] : nlohmann::json(),
        has ? model.extra.value("step_sizes", nlohmann::json()) : nlohmann::json());
    return model;
}

ServedModel serve(const std::string& path, int64_t ratio) {
    ServedModel served;
    served.model =
        load_inference_model(path.empty() ? default_model_for_ratio(ratio) : path, ratio);
    served.ratio = output_ratio(*served.model.backbone, ratio);
    return served;
}

std::string default_model_path(const std::string& name) {
    if (const char* dir = std::getenv("PUMETA_MODELS"))
        return (std::filesystem::path(dir) / name).string();
    return (std::filesystem::path(PUMETA_SOURCE_DIR) / "models" / name).string();
}

std::string model_file_for_ratio(const std::string& dir, const std::string& name, int64_t ratio,
                                 const std::string& suffix) {
    for (int64_t base : {ratio, int64_t{8}, int64_t{4}, int64_t{2}}) {
        int64_t r = ratio;
        while (r % base == 0 && r > base) r /= base;
        if (r != base) continue;
        std::filesystem::path file =
            std::filesystem::path(dir) / (name + "-x" + std::to_string(base) + suffix + ".pt");
        if (std::filesystem::exists(file)) return file.string();
    }
    return "";
}

std::string default_model_for_ratio(int64_t ratio) {
    if (ratio <= 1) return default_model_path();
    std::string dir = std::filesystem::path(default_model_path()).parent_path().string();
    std::string found = model_file_for_ratio(dir, "pugcn", ratio);
    return found.empty() ? default_model_path() : found;
}

}  // namespace pumeta
