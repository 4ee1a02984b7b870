#include "pumeta/models/config_fields.h"

#include <gtest/gtest.h>

#include <cstdint>
#include <string>
#include <vector>

#include "pumeta/core/error.h"
#include "support/test_util.h"

namespace pumeta {

namespace {

// A backbone-like options struct with one field of every reader.
struct Options {
    std::string preset = "small";
    int64_t width = 4;
    int64_t depth = 2;
    int64_t copies = 1;
    double weight = 0.5;
    double scale = 1.0;
    bool flag = false;
    uint64_t seed = 0;
    std::string downsampler = "fps";
    std::string mode = "a";
    std::vector<int64_t> sizes = {1, 2};
};

template <class Self, class Visit>
void visit_fields(Self& o, Visit&& visit) {
    visit("preset", o.preset, field::string);
    visit("width", o.width, field::positive_int);
    visit("depth", o.depth, field::positive_int);
    visit("copies", o.copies, field::int_range(0, 3));
    visit("weight", o.weight, field::non_negative_number);
    visit("scale", o.scale, field::positive_number);
    visit("flag", o.flag, field::boolean);
    visit("seed", o.seed, field::seed);
    visit("downsampler", o.downsampler, field::downsampler);
    visit("mode", o.mode, field::one_of({"a", "b", "c"}));
    visit("sizes", o.sizes, field::positive_ints(2));
}

void apply_preset(Options& o) {
    if (o.preset == "small") {
        o.width = 4, o.depth = 2;
    } else if (o.preset == "large") {
        o.width = 64, o.depth = 8;
    } else {
        throw_input_error("test config", "unknown preset '{}'", o.preset);
    }
}

Options read(const nlohmann::json& config) {
    Options o;
    read_backbone_config(
        config, "test", [&](auto&& visit) { visit_fields(o, visit); }, [&] { apply_preset(o); });
    return o;
}

nlohmann::json write(const Options& o) {
    return write_backbone_config("test", [&](auto&& visit) { visit_fields(o, visit); });
}

// The message of the InputError that reading `config` throws, "no error" without one.
std::string error_of(const nlohmann::json& config) {
    try {
        read(config);
    } catch (const InputError& e) {
        return e.what();
    }
    return "no error";
}

}  // namespace

TEST(ConfigFields, WrongValuesNameTheFieldTheRuleAndTheValue) {
    EXPECT_EQ(error_of({{"width", "3"}}),
              "test config: 'width' must be an integer from 1 to 1048576, found \"3\"");
    EXPECT_EQ(error_of({{"width", 0}}),
              "test config: 'width' must be an integer from 1 to 1048576, found 0");
    EXPECT_EQ(error_of({{"depth", 1.5}}),
              "test config: 'depth' must be an integer from 1 to 1048576, found 1.5");
    EXPECT_EQ(error_of({{"depth", (1 << 20) + 1}}),
              "test config: 'depth' must be an integer from 1 to 1048576, found 1048577");
    EXPECT_EQ(error_of({{"copies", 4}}),
              "test config: 'copies' must be an integer from 0 to 3, found 4");
    EXPECT_EQ(error_of({{"weight", -1}}),
              "test config: 'weight' must be a non-negative number, found -1");
    EXPECT_EQ(error_of({{"scale", 0}}), "test config: 'scale' must be a positive number, found 0");
    EXPECT_EQ(error_of({{"scale", "1"}}),
              "test config: 'scale' must be a positive number, found \"1\"");
    EXPECT_EQ(error_of({{"flag", 1}}), "test config: 'flag' must be true or false, found 1");
    EXPECT_EQ(error_of({{"seed", -1}}),
              "test config: 'seed' must be a non-negative integer, found -1");
    EXPECT_EQ(error_of({{"preset", 3}}), "test config: 'preset' must be a string, found 3");
    EXPECT_EQ(error_of({{"mode", "d"}}),
              "test config: 'mode' must be \"a\", \"b\" or \"c\", found \"d\"");
    EXPECT_EQ(error_of({{"mode", nullptr}}),
              "test config: 'mode' must be \"a\", \"b\" or \"c\", found null");
    EXPECT_EQ(error_of({{"sizes", {1, 2, 3}}}),
              "test config: 'sizes' must be an array of 2 integers, found [1,2,3]");
    EXPECT_EQ(error_of({{"sizes", {1, -2}}}),
              "test config: 'sizes' must be an integer from 1 to 1048576, found -2");
    EXPECT_NE(error_of({{"downsampler", "grid"}}).find("grid"), std::string::npos);
    EXPECT_EQ(error_of({{"downsampler", 2}}),
              "test config: 'downsampler' must be a string, found 2");
    // Boundaries are accepted.
    Options edge = read({{"width", 1 << 20},
                         {"copies", 0},
                         {"weight", 0},
                         {"seed", UINT64_MAX},
                         {"sizes", {1, 1}},
                         {"mode", "c"}});
    EXPECT_EQ(edge.width, 1 << 20);
    EXPECT_EQ(edge.copies, 0);
    EXPECT_EQ(edge.weight, 0.0);
    EXPECT_EQ(edge.seed, UINT64_MAX);
    EXPECT_EQ(edge.sizes, (std::vector<int64_t>{1, 1}));
    EXPECT_EQ(edge.mode, "c");
}

TEST(ConfigFields, RejectsUnknownFieldsOtherBackbonesAndNonObjects) {
    EXPECT_EQ(error_of({{"wdth", 8}}), "test config: unknown field 'wdth'");
    EXPECT_EQ(error_of({{"comment", "x"}}), "test config: unknown field 'comment'");
    EXPECT_EQ(error_of({{"backbone", "pugcn"}}),
              "test config: 'backbone' must be \"test\", found \"pugcn\"");
    EXPECT_EQ(error_of(nlohmann::json::array({1})), "test config: expected a JSON object");
    // Keys are checked in the config's order: the first offending key is reported.
    EXPECT_EQ(error_of({{"aaa", 1}, {"width", 0}}), "test config: unknown field 'aaa'");
    EXPECT_EQ(error_of({{"width", 0}, {"zzz", 1}}),
              "test config: 'width' must be an integer from 1 to 1048576, found 0");
    // Without a preset function, "preset" is a field like any other: unknown here.
    Options o;
    EXPECT_TRUE(test::throws_input_error(
        [&] {
            read_backbone_config({{"preset", "large"}}, "bare", [&](auto&& visit) {
                visit("width", o.width, field::positive_int);
            });
        },
        {"bare config", "unknown field 'preset'"}));
    EXPECT_EQ(o.width, 4);
}

TEST(ConfigFields, PresetIsAppliedFirstAndExplicitFieldsOverrideIt) {
    // "depth" sorts before "preset" and "width" after it: both override.
    Options o = read({{"backbone", "test"}, {"depth", 3}, {"preset", "large"}, {"width", 5}});
    EXPECT_EQ(o.preset, "large");
    EXPECT_EQ(o.depth, 3);
    EXPECT_EQ(o.width, 5);
    Options large = read({{"preset", "large"}});
    EXPECT_EQ(large.width, 64);
    EXPECT_EQ(large.depth, 8);
    Options defaults = read(nlohmann::json::object());
    EXPECT_EQ(defaults.preset, "small");
    EXPECT_EQ(defaults.width, 4);
    EXPECT_EQ(error_of({{"preset", "huge"}}), "test config: unknown preset 'huge'");
}

TEST(ConfigFields, WritesEveryFieldAndReadsItBack) {
    Options o = read({{"preset", "large"},
                      {"copies", 3},
                      {"weight", 2.5},
                      {"scale", 0.25},
                      {"flag", true},
                      {"seed", 7},
                      {"downsampler", "random"},
                      {"mode", "b"},
                      {"sizes", {3, 4}}});
    nlohmann::json j = write(o);
    const nlohmann::json expected = {
        {"backbone", "test"},  {"preset", "large"},       {"width", 64},   {"depth", 8},
        {"copies", 3},         {"weight", 2.5},           {"scale", 0.25}, {"flag", true},
        {"seed", uint64_t{7}}, {"downsampler", "random"}, {"mode", "b"},   {"sizes", {3, 4}}};
    EXPECT_EQ(j, expected);
    EXPECT_TRUE(j["seed"].is_number_unsigned());
    EXPECT_TRUE(j["weight"].is_number_float());
    EXPECT_EQ(write(read(j)), j);
    // A written default config reads back to the defaults.
    EXPECT_EQ(write(read(write(Options()))), write(Options()));
}

}  // namespace pumeta
