#include "pumeta/models/config_fields.h"

#include "pumeta/core/error.h"
#include "pumeta/models/downsample.h"

namespace pumeta {

namespace field {

int64_t positive_int(const nlohmann::json& value, const std::string& key,
                     const std::string& context) {
    return int_range(1, 1 << 20)(value, key, context);
}

double positive_number(const nlohmann::json& value, const std::string& key,
                       const std::string& context) {
    if (!value.is_number() || !(value.get<double>() > 0))
        throw_input_error(context, "'{}' must be a positive number, found {}", key, value.dump());
    return value.get<double>();
}

double non_negative_number(const nlohmann::json& value, const std::string& key,
                           const std::string& context) {
    if (!value.is_number() || !(value.get<double>() >= 0))
        throw_input_error(context, "'{}' must be a non-negative number, found {}", key,
                          value.dump());
    return value.get<double>();
}

bool boolean(const nlohmann::json& value, const std::string& key, const std::string& context) {
    if (!value.is_boolean())
        throw_input_error(context, "'{}' must be true or false, found {}", key, value.dump());
    return value.get<bool>();
}

std::string string(const nlohmann::json& value, const std::string& key,
                   const std::string& context) {
    if (!value.is_string())
        throw_input_error(context, "'{}' must be a string, found {}", key, value.dump());
    return value.get<std::string>();
}

uint64_t seed(const nlohmann::json& value, const std::string& key, const std::string& context) {
    bool non_negative =
        value.is_number_unsigned() || (value.is_number_integer() && value.get<int64_t>() >= 0);
    if (!non_negative)
        throw_input_error(context, "'{}' must be a non-negative integer, found {}", key,
                          value.dump());
    return value.get<uint64_t>();
}

std::string downsampler(const nlohmann::json& value, const std::string& key,
                        const std::string& context) {
    std::string name = string(value, key, context);
    check_downsampler(name, context);
    return name;
}

int64_t IntRange::operator()(const nlohmann::json& value, const std::string& key,
                             const std::string& context) const {
    if (!value.is_number_integer() || value.get<int64_t>() < min || value.get<int64_t>() > max)
        throw_input_error(context, "'{}' must be an integer from {} to {}, found {}", key, min, max,
                          value.dump());
    return value.get<int64_t>();
}

std::string OneOf::operator()(const nlohmann::json& value, const std::string& key,
                              const std::string& context) const {
    for (const std::string& name : names)
        if (value == name) return name;
    std::string list;
    for (size_t i = 0; i < names.size(); ++i)
        list += (i == 0                  ? ""
                 : i + 1 == names.size() ? " or "
                                         : ", ") +
                nlohmann::json(names[i]).dump();
    throw_input_error(context, "'{}' must be {}, found {}", key, list, value.dump());
}

std::vector<int64_t> PositiveInts::operator()(const nlohmann::json& value, const std::string& key,
                                              const std::string& context) const {
    if (!value.is_array() || value.size() != size)
        throw_input_error(context, "'{}' must be an array of {} integers, found {}", key, size,
                          value.dump());
    std::vector<int64_t> ints;
    for (const nlohmann::json& item : value) ints.push_back(positive_int(item, key, context));
    return ints;
}

}  // namespace field

namespace config_fields_detail {

void check_object(const nlohmann::json& config, const std::string& context) {
    if (!config.is_object()) throw_input_error(context, "expected a JSON object");
}

void check_backbone(const nlohmann::json& value, const std::string& kind,
                    const std::string& context) {
    if (value != kind)
        throw_input_error(context, "'backbone' must be \"{}\", found {}", kind, value.dump());
}

void throw_unknown_field(const std::string& key, const std::string& context) {
    throw_input_error(context, "unknown field '{}'", key);
}

}  // namespace config_fields_detail

}  // namespace pumeta
