// Reading JSON config files for the CLI, with errors naming the file.
#pragma once

#include <nlohmann/json.hpp>
#include <string>

namespace pumeta::cli {

/// Parses a JSON file; InputError "<path>: ..." when missing or malformed.
nlohmann::json read_json_file(const std::string& path);

/// Applies "key=value" overrides (value parsed as JSON, else taken as a string) to a config:
/// `--set steps=100 --set backbone.channels=16`.
void apply_overrides(nlohmann::json& config, const std::vector<std::string>& overrides);

}  // namespace pumeta::cli
