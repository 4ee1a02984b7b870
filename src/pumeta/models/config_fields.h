// Backbone configs: one list of an options struct's JSON fields, each with the reader that
// checks its value, used both to read the struct and to write it back.
//
//   template <class Self, class Visit>
//   void visit_fields(Self& o, Visit&& visit) {
//       visit("preset", o.preset, field::string);
//       visit("ratio", o.ratio, field::positive_int);
//       visit("downsampler", o.downsampler, field::downsampler);
//   }
//   Options Options::from_json(const nlohmann::json& config) {
//       Options o;
//       read_backbone_config(config, "kind", [&](auto&& visit) { visit_fields(o, visit); },
//                            [&] { apply_preset(o); });
//       ...checks across fields...
//   }
//   nlohmann::json Options::to_json() const {
//       return write_backbone_config("kind", [&](auto&& visit) { visit_fields(*this, visit); });
//   }
//
// A wrong value gets the same one-line InputError in every backbone:
// "<kind> config: '<key>' must be ..., found <value>".
#pragma once

#include <cstddef>
#include <cstdint>
#include <functional>
#include <nlohmann/json.hpp>
#include <string>
#include <utility>
#include <vector>

namespace pumeta {

/// Readers of one field: T reader(value, key, context) returns the value or throws
/// InputError "<context>: '<key>' must be ..., found <value>".
namespace field {

/// An integer from 1 to 2^20 (no size of any network comes near it; products of sizes stay
/// far from overflow).
int64_t positive_int(const nlohmann::json& value, const std::string& key,
                     const std::string& context);
double positive_number(const nlohmann::json& value, const std::string& key,
                       const std::string& context);
double non_negative_number(const nlohmann::json& value, const std::string& key,
                           const std::string& context);
bool boolean(const nlohmann::json& value, const std::string& key, const std::string& context);
std::string string(const nlohmann::json& value, const std::string& key, const std::string& context);
/// A non-negative integer.
uint64_t seed(const nlohmann::json& value, const std::string& key, const std::string& context);
/// One of downsampler_names().
std::string downsampler(const nlohmann::json& value, const std::string& key,
                        const std::string& context);

/// An integer from `min` to `max`.
struct IntRange {
    int64_t min, max;
    int64_t operator()(const nlohmann::json& value, const std::string& key,
                       const std::string& context) const;
};
inline IntRange int_range(int64_t min, int64_t max) { return {min, max}; }

/// One of `names`.
struct OneOf {
    std::vector<std::string> names;
    std::string operator()(const nlohmann::json& value, const std::string& key,
                           const std::string& context) const;
};
inline OneOf one_of(std::vector<std::string> names) { return {std::move(names)}; }

/// An array of `size` positive_int values.
struct PositiveInts {
    size_t size;
    std::vector<int64_t> operator()(const nlohmann::json& value, const std::string& key,
                                    const std::string& context) const;
};
inline PositiveInts positive_ints(size_t size) { return {size}; }

}  // namespace field

namespace config_fields_detail {

void check_object(const nlohmann::json& config, const std::string& context);
void check_backbone(const nlohmann::json& value, const std::string& kind,
                    const std::string& context);
[[noreturn]] void throw_unknown_field(const std::string& key, const std::string& context);

/// Reads `value` into the field named `key`; false when `fields` visits none.
template <class Fields>
bool read_field(const nlohmann::json& value, const std::string& key, const std::string& context,
                Fields& fields) {
    bool found = false;
    fields([&](const char* name, auto& member, const auto& read) {
        if (found || key != name) return;
        member = read(value, key, context);
        found = true;
    });
    return found;
}

}  // namespace config_fields_detail

/// Reads the config {"backbone": kind, ...} into the fields that `fields` visits (called with
/// a visitor `visit(key, member, reader)`); absent fields keep their values. With
/// `apply_preset`, the field "preset" is read first and apply_preset() called, so that the
/// other fields override the preset whatever the key order. Fields are read in the config's
/// key order. InputError "<kind> config: ..." for a non-object, another backbone, an unknown
/// field or a value its reader rejects.
template <class Fields>
void read_backbone_config(const nlohmann::json& config, const std::string& kind, Fields&& fields,
                          const std::function<void()>& apply_preset = nullptr) {
    using namespace config_fields_detail;
    const std::string context = kind + " config";
    check_object(config, context);
    if (auto preset = config.find("preset"); apply_preset && preset != config.end()) {
        if (!read_field(*preset, "preset", context, fields)) throw_unknown_field("preset", context);
        apply_preset();
    }
    for (const auto& [key, value] : config.items()) {
        if (key == "backbone")
            check_backbone(value, kind, context);
        else if (!(apply_preset && key == "preset") && !read_field(value, key, context, fields))
            throw_unknown_field(key, context);
    }
}

/// {"backbone": kind} and every field that `fields` visits.
template <class Fields>
nlohmann::json write_backbone_config(const std::string& kind, Fields&& fields) {
    nlohmann::json j = {{"backbone", kind}};
    fields([&](const char* name, const auto& member, const auto&) { j[name] = member; });
    return j;
}

}  // namespace pumeta
