#include "pumeta/cli/config_file.h"

#include <filesystem>

#include "pumeta/core/error.h"
#include "pumeta/geometry/io/file.h"

namespace pumeta::cli {

nlohmann::json read_json_file(const std::string& path) {
    const std::string text = io::read_whole_file(path);
    try {
        return nlohmann::json::parse(text, nullptr, true, /*ignore_comments=*/true);
    } catch (const nlohmann::json::parse_error& e) {
        throw_input_error(path, "invalid JSON at byte {}", e.byte);
    } catch (const nlohmann::json::exception& e) {  // e.g. a number beyond double's range
        throw_input_error(path, "invalid JSON: {}", e.what());
    }
}

void apply_overrides(nlohmann::json& config, const std::vector<std::string>& overrides) {
    for (const std::string& item : overrides) {
        auto eq = item.find('=');
        if (eq == std::string::npos || eq == 0)
            throw_input_error("--set", "expected key=value, found '{}'", item);
        std::string key = item.substr(0, eq), text = item.substr(eq + 1);
        nlohmann::json value;
        try {
            value = nlohmann::json::parse(text);
        } catch (const nlohmann::json::exception&) {  // not JSON (or out of range): a string
            value = text;
        }
        nlohmann::json* node = &config;
        for (size_t start = 0;;) {
            auto dot = key.find('.', start);
            std::string part = key.substr(start, dot == std::string::npos ? dot : dot - start);
            if (dot == std::string::npos) {
                (*node)[part] = value;
                break;
            }
            node = &(*node)[part];
            start = dot + 1;
        }
    }
}

}  // namespace pumeta::cli
