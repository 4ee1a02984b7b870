#include "pumeta/eval/reproduce_models.h"

#include <filesystem>

#include "pumeta/inference/model_file.h"
#include "pumeta/models/checkpoint.h"

namespace pumeta {

std::optional<std::string> ModelFiles::find(const std::string& backbone, int64_t ratio,
                                            bool meta) const {
    const std::string suffix = meta ? "-meta" : "";
    std::string file = model_file_for_ratio(models_dir_, backbone, ratio, suffix);
    if (file.empty()) {
        std::string main = model_file_for_ratio(models_dir_, backbone, main_ratio_, suffix);
        if (!main.empty() && serves_ratio(main, ratio)) file = main;
    }
    if (file.empty()) {
        // One file for several ratios, named without one (MPU's levels, Meta-PU's any ratio).
        std::filesystem::path any =
            std::filesystem::path(models_dir_) / (backbone + suffix + ".pt");
        if (std::filesystem::exists(any) && serves_ratio(any.string(), ratio)) file = any.string();
    }
    if (file.empty()) return std::nullopt;
    return file;
}

bool ModelFiles::serves_ratio(const std::string& file, int64_t ratio) const {
    auto key = std::make_pair(file, ratio);
    auto found = serves_ratio_.find(key);
    if (found == serves_ratio_.end())
        found = serves_ratio_
                    .emplace(key,
                             [&] {
                                 auto backbone = load_checkpoint(file).backbone;
                                 return backbone->ratio() == ratio ||
                                        !backbone->config_for_ratio(ratio).is_null();
                             }())
                    .first;
    return found->second;
}

}  // namespace pumeta
