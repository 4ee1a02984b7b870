#include "pumeta/data/layout.h"

#include <fmt/format.h>

namespace pumeta::layout {

namespace fs = std::filesystem;

std::string ratio_tag(int64_t ratio) { return fmt::format("x{}", ratio); }

fs::path cases_root(const fs::path& dataset) { return dataset / "cases"; }

fs::path cases_dir(const fs::path& dataset, const std::string& set, int64_t ratio) {
    return cases_root(dataset) / set / ratio_tag(ratio);
}

fs::path case_index_path(const fs::path& cases_dir) { return cases_dir / "cases.json"; }

fs::path case_mesh_path(const fs::path& dataset, const std::string& set,
                        const std::string& case_name) {
    return cases_root(dataset) / set / "meshes" / (case_name + ".ply");
}

std::string case_mesh_entry(const std::string& case_name) {
    return "../../meshes/" + case_name + ".ply";
}

std::string patch_set_file(const std::string& split, int64_t ratio) {
    return fmt::format("{}-{}.tensors", split, ratio_tag(ratio));
}

fs::path patch_set_path(const fs::path& dataset, const std::string& split, int64_t ratio) {
    return dataset / patch_set_file(split, ratio);
}

}  // namespace pumeta::layout
