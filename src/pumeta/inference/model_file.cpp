#include "pumeta/inference/model_file.h"

#include <cstdlib>
#include <filesystem>

#include "pumeta/core/error.h"
#include "pumeta/geometry/io/file.h"
#include "pumeta/inference/upsample.h"
#include "pumeta/models/checkpoint.h"

namespace pumeta {

namespace {

/// `backbone` rebuilt for `ratio` with its parameters and buffers, when its weights serve that
/// ratio; else `backbone` itself.
std::unique_ptr<Backbone> at_ratio(std::unique_ptr<Backbone> backbone, int64_t ratio) {
    if (ratio <= 0 || ratio == backbone->ratio()) return backbone;
    std::unique_ptr<Backbone> rebuilt = share_weights_at(*backbone, ratio);
    return rebuilt ? std::move(rebuilt) : std::move(backbone);
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
    served.path = path.empty() ? default_model_for_ratio(ratio) : path;
    served.model = load_inference_model(served.path, ratio);
    served.ratio = output_ratio(*served.model.backbone, ratio);
    return served;
}

std::string models_dir() {
    if (const char* dir = std::getenv("PUMETA_MODELS")) return dir;
    std::error_code error;
    // An installed binary uses the models installed beside it (PREFIX/bin/pumeta ->
    // PREFIX/share/pumeta/models), wherever the prefix was moved (a package unpacked elsewhere).
    const std::filesystem::path executable = std::filesystem::read_symlink("/proc/self/exe", error);
    if (!error) {
        const std::filesystem::path beside =
            executable.parent_path().parent_path() / "share" / "pumeta" / "models";
        if (std::filesystem::exists(beside / "defaults.json", error)) return beside.string();
    }
    // PUMETA_INSTALLED_MODELS_DIR (set by CMake on this file only) is where `cmake --install`
    // puts the models: an installed library uses them, a build tree its source tree's.
    const std::filesystem::path installed = PUMETA_INSTALLED_MODELS_DIR;
    if (std::filesystem::exists(installed / "defaults.json", error)) return installed.string();
    return (std::filesystem::path(PUMETA_SOURCE_DIR) / "models").string();
}

std::string default_model_family() {
    const std::filesystem::path file = std::filesystem::path(models_dir()) / "defaults.json";
    nlohmann::json defaults;
    try {
        defaults = nlohmann::json::parse(io::read_whole_file(file.string()));
    } catch (const nlohmann::json::exception& e) {
        throw_input_error(file.string(), "invalid JSON: {}", e.what());
    }
    if (!defaults.is_object() || !defaults.contains("family") || !defaults["family"].is_string())
        throw_input_error(file.string(), "expected {{\"family\": NAME}}");
    return defaults["family"];
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
    const std::string family = default_model_family();
    const std::string fallback = (std::filesystem::path(models_dir()) /
                                  (family + "-x" + std::to_string(kDefaultRatio) + ".pt"))
                                     .string();
    if (ratio <= 1) return fallback;
    std::string found = model_file_for_ratio(models_dir(), family, ratio);
    return found.empty() ? fallback : found;
}

}  // namespace pumeta
