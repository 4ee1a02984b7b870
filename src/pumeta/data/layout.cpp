#include "pumeta/data/layout.h"

#include <fmt/format.h>

#include <fstream>

#include "pumeta/core/error.h"

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

nlohmann::json read_case_index(const fs::path& cases_dir) {
    const fs::path index_file = case_index_path(cases_dir);
    if (!fs::exists(index_file))
        throw_input_error(cases_dir.string(),
                          "no cases.json: not a test-case directory of make-dataset");
    nlohmann::json index;
    try {
        index = nlohmann::json::parse(std::ifstream(index_file));
    } catch (const nlohmann::json::parse_error& e) {
        throw_input_error(index_file.string(), "invalid JSON at byte {}", e.byte);
    } catch (const nlohmann::json::exception& e) {  // e.g. a number beyond double's range
        throw_input_error(index_file.string(), "invalid JSON: {}", e.what());
    }
    if (!index.is_object() || !index.contains("ratio") || !index["ratio"].is_number_integer() ||
        index["ratio"].get<int64_t>() < 1 || !index.contains("cases") || !index["cases"].is_array())
        throw_input_error(index_file.string(), "expected {{\"ratio\": R, \"cases\": [...]}}");
    return index;
}

}  // namespace pumeta::layout
