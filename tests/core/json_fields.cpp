#include "pumeta/core/json_fields.h"

#include <gtest/gtest.h>

#include <map>
#include <string>
#include <vector>

namespace pumeta {
namespace {

struct Inner {
    int64_t count = 1;
    static Inner from_json(const nlohmann::json& j) {
        if (!j.is_object()) throw_input_error("inner", "expected an object");
        Inner inner;
        inner.count = j.value("count", inner.count);
        return inner;
    }
    nlohmann::json to_json() const { return {{"count", count}}; }
};

struct Config {
    std::string name = "a";
    int64_t steps = 10;
    uint64_t seed = 1;
    double lr = 0.5;
    bool augment = true;
    std::vector<std::string> adapt;
    std::vector<int64_t> ratios = {4};
    std::vector<double> noise;
    nlohmann::json anything;
    Inner inner;
    std::vector<Inner> inners;
    std::map<std::string, double> rates;
};

template <class Self, class Visit>
void visit_fields(Self& c, Visit&& visit) {
    visit("name", c.name);
    visit("steps", c.steps);
    visit("seed", c.seed);
    visit("lr", c.lr);
    visit("augment", c.augment);
    visit("adapt", c.adapt);
    visit("ratios", c.ratios);
    visit("noise", c.noise);
    visit("anything", c.anything);
    visit("inner", c.inner);
    visit("inners", c.inners);
    visit("rates", c.rates);
}

Config read(const nlohmann::json& j) {
    Config c;
    read_fields(j, "test config", [&](auto&& visit) { visit_fields(c, visit); });
    return c;
}

std::string error_of(const nlohmann::json& j) {
    try {
        read(j);
    } catch (const InputError& e) {
        return e.what();
    }
    return "no error";
}

TEST(JsonFields, ReadsGivenFieldsAndKeepsDefaultsForAbsentOnes) {
    Config c = read({{"steps", 42},
                     {"lr", 2},
                     {"adapt", {"up.", "out."}},
                     {"comment", "ignored"},
                     {"inner", {{"count", 7}}},
                     {"anything", {1, "x"}}});
    EXPECT_EQ(c.steps, 42);
    EXPECT_DOUBLE_EQ(c.lr, 2.0);  // an integer is a valid number
    EXPECT_EQ(c.adapt, (std::vector<std::string>{"up.", "out."}));
    EXPECT_EQ(c.inner.count, 7);
    EXPECT_EQ(c.anything, nlohmann::json({1, "x"}));
    EXPECT_EQ(c.name, "a");
    EXPECT_EQ(c.seed, 1u);
    EXPECT_TRUE(c.augment);
}

TEST(JsonFields, WriteThenReadRoundTripsEveryField) {
    Config c;
    c.name = "b", c.steps = -3, c.seed = 18446744073709551615ull, c.lr = 1e-7;
    c.augment = false, c.adapt = {"head."}, c.anything = {{"k", 1}}, c.inner.count = 4;
    c.ratios = {8, 16}, c.noise = {0.5, 2};
    c.inners = {Inner{2}, Inner{3}}, c.rates = {{"pugcn", 0.01}, {"dispu-x4", 1e-6}};
    const Config& view = c;
    nlohmann::json j = write_fields([&](auto&& visit) { visit_fields(view, visit); });
    EXPECT_EQ(j.size(), 12u);
    EXPECT_EQ(j["inner"], nlohmann::json({{"count", 4}}));
    EXPECT_EQ(j["inners"], nlohmann::json::parse(R"([{"count":2},{"count":3}])"));
    Config back = read(j);
    EXPECT_EQ(back.name, "b");
    EXPECT_EQ(back.steps, -3);
    EXPECT_EQ(back.seed, 18446744073709551615ull);
    EXPECT_DOUBLE_EQ(back.lr, 1e-7);
    EXPECT_FALSE(back.augment);
    EXPECT_EQ(back.adapt, c.adapt);
    EXPECT_EQ(back.anything, c.anything);
    EXPECT_EQ(back.inner.count, 4);
    EXPECT_EQ(back.ratios, (std::vector<int64_t>{8, 16}));
    EXPECT_EQ(back.noise, (std::vector<double>{0.5, 2.0}));
    ASSERT_EQ(back.inners.size(), 2u);
    EXPECT_EQ(back.inners[1].count, 3);
    EXPECT_EQ(back.rates, c.rates);
}

TEST(JsonFields, UnknownFieldsAndWrongTypesAreInputErrorsNamingTheField) {
    EXPECT_EQ(error_of({{"stpes", 1}}), "test config: unknown field 'stpes'");
    EXPECT_EQ(error_of({{"steps", "ten"}}),
              "test config: 'steps' must be an integer, found \"ten\"");
    EXPECT_EQ(error_of({{"steps", 1.5}}), "test config: 'steps' must be an integer, found 1.5");
    EXPECT_EQ(error_of({{"seed", -1}}),
              "test config: 'seed' must be a non-negative integer, found -1");
    EXPECT_EQ(error_of({{"lr", "fast"}}), "test config: 'lr' must be a number, found \"fast\"");
    EXPECT_EQ(error_of({{"augment", 1}}), "test config: 'augment' must be true or false, found 1");
    EXPECT_EQ(error_of({{"name", 3}}), "test config: 'name' must be a string, found 3");
    EXPECT_EQ(error_of({{"adapt", {"up.", 2}}}),
              "test config: 'adapt' must be a list of strings, found [\"up.\",2]");
    EXPECT_EQ(error_of({{"ratios", {4, 8.5}}}),
              "test config: 'ratios' must be a list of integers, found [4,8.5]");
    EXPECT_EQ(error_of({{"noise", 0.5}}),
              "test config: 'noise' must be a list of numbers, found 0.5");
    EXPECT_EQ(error_of({{"inner", 5}}), "inner: expected an object");
    EXPECT_EQ(error_of({{"inners", {{{"count", 1}}, 5}}}), "inner: expected an object");
    EXPECT_EQ(error_of({{"inners", 5}}),
              "test config: 'inners' must be a list of objects, found 5");
    EXPECT_EQ(error_of({{"rates", {{"pugcn", "fast"}}}}),
              "test config: 'rates' must be an object of numbers, found "
              "{\"pugcn\":\"fast\"}");
    EXPECT_EQ(error_of(nlohmann::json::array({1})),
              "test config: expected a JSON object, found [1]");
}

}  // namespace
}  // namespace pumeta
