#include "pumeta/models/config_fields.h"

#include "pumeta/core/error.h"
#include "pumeta/models/downsample.h"

namespace pumeta {

int64_t positive_int_field(const nlohmann::json& value, const std::string& key,
                           const std::string& context) {
    // No size of any network comes near the upper bound; it keeps products of sizes far from
    // overflow.
    constexpr int64_t kMax = 1 << 20;
    if (!value.is_number_integer() || value.get<int64_t>() < 1 || value.get<int64_t>() > kMax)
        throw_input_error(context, "'{}' must be an integer from 1 to {}, found {}", key, kMax,
                          value.dump());
    return value.get<int64_t>();
}

double positive_number_field(const nlohmann::json& value, const std::string& key,
                             const std::string& context) {
    if (!value.is_number() || !(value.get<double>() > 0))
        throw_input_error(context, "'{}' must be a positive number, found {}", key, value.dump());
    return value.get<double>();
}

double non_negative_number_field(const nlohmann::json& value, const std::string& key,
                                 const std::string& context) {
    if (!value.is_number() || !(value.get<double>() >= 0))
        throw_input_error(context, "'{}' must be a non-negative number, found {}", key,
                          value.dump());
    return value.get<double>();
}

uint64_t seed_field(const nlohmann::json& value, const std::string& context) {
    bool non_negative =
        value.is_number_unsigned() || (value.is_number_integer() && value.get<int64_t>() >= 0);
    if (!non_negative)
        throw_input_error(context, "'seed' must be a non-negative integer, found {}", value.dump());
    return value.get<uint64_t>();
}

std::string downsampler_field(const nlohmann::json& value, const std::string& context) {
    if (!value.is_string())
        throw_input_error(context, "'downsampler' must be a string, found {}", value.dump());
    std::string name = value.get<std::string>();
    check_downsampler(name, context);
    return name;
}

}  // namespace pumeta
