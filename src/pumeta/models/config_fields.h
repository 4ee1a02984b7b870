// Typed readers of the JSON fields of backbone configs, shared by every backbone so that a
// wrong value gets the same one-line message everywhere: "<context>: '<key>' must be ...".
#pragma once

#include <cstdint>
#include <nlohmann/json.hpp>
#include <string>

namespace pumeta {

int64_t positive_int_field(const nlohmann::json& value, const std::string& key,
                           const std::string& context);
double positive_number_field(const nlohmann::json& value, const std::string& key,
                             const std::string& context);
double non_negative_number_field(const nlohmann::json& value, const std::string& key,
                                 const std::string& context);
/// Field "seed": a non-negative integer.
uint64_t seed_field(const nlohmann::json& value, const std::string& context);
/// Field "downsampler": one of downsampler_names().
std::string downsampler_field(const nlohmann::json& value, const std::string& context);

}  // namespace pumeta
