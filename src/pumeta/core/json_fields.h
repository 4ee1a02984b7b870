// One list of a config struct's JSON fields, used both to read and to write it.
//
//   template <class Self, class Visit>
//   void visit_fields(Self& c, Visit&& visit) {
//       visit("steps", c.steps);
//       visit("lr", c.lr);
//   }
//   Config Config::from_json(const nlohmann::json& j) {
//       Config c;
//       read_fields(j, "train config", [&](auto&& visit) { visit_fields(c, visit); });
//       ...validation...
//   }
//   nlohmann::json Config::to_json() const { return write_fields(... visit_fields(*this, ...)); }
//
// Reading rejects unknown fields and wrong types with an InputError naming the field
// ("train config: 'steps' must be an integer, found \"ten\""); "comment" is always allowed.
// Nested configs are members with their own static from_json and to_json.
#pragma once

#include <cstdint>
#include <nlohmann/json.hpp>
#include <set>
#include <string>
#include <type_traits>
#include <vector>

#include "pumeta/core/error.h"

namespace pumeta {

namespace json_fields_detail {

template <class T, class = void>
struct IsConfig : std::false_type {};
template <class T>
struct IsConfig<T, std::void_t<decltype(T::from_json(std::declval<const nlohmann::json&>())),
                               decltype(std::declval<const T&>().to_json())>> : std::true_type {};

template <class T>
void read_value(const nlohmann::json& value, const std::string& key, const std::string& context,
                T& member) {
    auto wrong = [&](const char* expected) {
        throw_input_error(context, "'{}' must be {}, found {}", key, expected, value.dump());
    };
    if constexpr (std::is_same_v<T, bool>) {
        if (!value.is_boolean()) wrong("true or false");
        member = value.get<bool>();
    } else if constexpr (std::is_same_v<T, uint64_t>) {
        if (!value.is_number_integer() || (!value.is_number_unsigned() && value.get<int64_t>() < 0))
            wrong("a non-negative integer");
        member = value.get<uint64_t>();
    } else if constexpr (std::is_integral_v<T>) {
        if (!value.is_number_integer()) wrong("an integer");
        member = value.get<T>();
    } else if constexpr (std::is_floating_point_v<T>) {
        if (!value.is_number()) wrong("a number");
        member = value.get<T>();
    } else if constexpr (std::is_same_v<T, std::string>) {
        if (!value.is_string()) wrong("a string");
        member = value.get<std::string>();
    } else if constexpr (std::is_same_v<T, std::vector<std::string>>) {
        if (!value.is_array()) wrong("a list of strings");
        for (const nlohmann::json& item : value)
            if (!item.is_string()) wrong("a list of strings");
        member = value.get<std::vector<std::string>>();
    } else if constexpr (std::is_same_v<T, nlohmann::json>) {
        member = value;
    } else {
        static_assert(IsConfig<T>::value, "a config field needs a supported type");
        member = T::from_json(value);
    }
}

template <class T>
nlohmann::json write_value(const T& member) {
    if constexpr (IsConfig<T>::value)
        return member.to_json();
    else
        return member;
}

}  // namespace json_fields_detail

/// Reads the fields that `bind` visits from the object `j`; `bind` is called with a
/// visitor `visit(key, member)`. Throws InputError "<context>: ..." for a non-object, an
/// unknown field or a value of the wrong type. Fields absent from `j` keep their values.
template <class Bind>
void read_fields(const nlohmann::json& j, const std::string& context, Bind&& bind) {
    if (!j.is_object()) throw_input_error(context, "expected a JSON object, found {}", j.dump());
    std::set<std::string> known;
    bind([&](const std::string& key, auto& member) {
        known.insert(key);
        if (auto it = j.find(key); it != j.end())
            json_fields_detail::read_value(*it, key, context, member);
    });
    for (const auto& [key, value] : j.items())
        if (key != "comment" && !known.count(key))
            throw_input_error(context, "unknown field '{}'", key);
}

/// The JSON object of every field that `bind` visits.
template <class Bind>
nlohmann::json write_fields(Bind&& bind) {
    nlohmann::json j = nlohmann::json::object();
    bind([&](const std::string& key, const auto& member) {
        j[key] = json_fields_detail::write_value(member);
    });
    return j;
}

}  // namespace pumeta
