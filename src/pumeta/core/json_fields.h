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
// Nested configs are members (or lists of members) with their own static from_json and
// to_json; string-keyed maps of scalars are objects.
#pragma once

#include <cstdint>
#include <map>
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
struct IsVector : std::false_type {};
template <class T>
struct IsVector<std::vector<T>> : std::true_type {};

template <class T>
struct IsConfigList : std::false_type {};
template <class T>
struct IsConfigList<std::vector<T>> : IsConfig<T> {};

template <class T>
struct IsStringMap : std::false_type {};
template <class T>
struct IsStringMap<std::map<std::string, T>> : std::true_type {};

/// Whether `value` can be read as a T, and how the error names T.
template <class T>
bool has_type(const nlohmann::json& value) {
    if constexpr (std::is_same_v<T, bool>)
        return value.is_boolean();
    else if constexpr (std::is_same_v<T, uint64_t>)
        return value.is_number_unsigned() ||
               (value.is_number_integer() && value.get<int64_t>() >= 0);
    else if constexpr (std::is_integral_v<T>)
        return value.is_number_integer();
    else if constexpr (std::is_floating_point_v<T>)
        return value.is_number();
    else
        return value.is_string();
}

template <class T>
const char* type_name() {
    if constexpr (std::is_same_v<T, bool>)
        return "true or false";
    else if constexpr (std::is_same_v<T, uint64_t>)
        return "a non-negative integer";
    else if constexpr (std::is_integral_v<T>)
        return "an integer";
    else if constexpr (std::is_floating_point_v<T>)
        return "a number";
    else
        return "a string";
}

template <class T>
const char* plural_name() {
    if constexpr (std::is_same_v<T, bool>)
        return "booleans";
    else if constexpr (std::is_integral_v<T>)
        return "integers";
    else if constexpr (std::is_floating_point_v<T>)
        return "numbers";
    else
        return "strings";
}

template <class T>
const char* list_name() {
    if constexpr (IsConfig<T>::value)
        return "a list of objects";
    else if constexpr (std::is_integral_v<T>)
        return "a list of integers";
    else if constexpr (std::is_floating_point_v<T>)
        return "a list of numbers";
    else
        return "a list of strings";
}

template <class T>
void read_value(const nlohmann::json& value, const std::string& key, const std::string& context,
                T& member) {
    if constexpr (std::is_same_v<T, nlohmann::json>) {
        member = value;
    } else if constexpr (IsConfig<T>::value) {
        member = T::from_json(value);
    } else if constexpr (IsConfigList<T>::value) {
        if (!value.is_array())
            throw_input_error(context, "'{}' must be {}, found {}", key,
                              list_name<typename T::value_type>(), value.dump());
        member.clear();
        for (const nlohmann::json& item : value) member.push_back(T::value_type::from_json(item));
    } else if constexpr (IsVector<T>::value) {
        using Item = typename T::value_type;
        bool ok = value.is_array();
        for (size_t i = 0; ok && i < value.size(); ++i) ok = has_type<Item>(value[i]);
        if (!ok)
            throw_input_error(context, "'{}' must be {}, found {}", key, list_name<Item>(),
                              value.dump());
        member = value.get<T>();
    } else if constexpr (IsStringMap<T>::value) {
        using Item = typename T::mapped_type;
        static_assert(std::is_arithmetic_v<Item> || std::is_same_v<Item, std::string>,
                      "a map field needs scalar values");
        bool ok = value.is_object();
        if (ok)
            for (const auto& [name, item] : value.items()) ok = ok && has_type<Item>(item);
        if (!ok)
            throw_input_error(context, "'{}' must be an object of {}, found {}", key,
                              plural_name<Item>(), value.dump());
        member = value.get<T>();
    } else {
        static_assert(std::is_arithmetic_v<T> || std::is_same_v<T, std::string>,
                      "a config field needs a supported type");
        if (!has_type<T>(value))
            throw_input_error(context, "'{}' must be {}, found {}", key, type_name<T>(),
                              value.dump());
        member = value.get<T>();
    }
}

template <class T>
nlohmann::json write_value(const T& member) {
    if constexpr (IsConfig<T>::value) {
        return member.to_json();
    } else if constexpr (IsConfigList<T>::value) {
        nlohmann::json list = nlohmann::json::array();
        for (const auto& item : member) list.push_back(item.to_json());
        return list;
    } else {
        return member;
    }
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
