// Every config the repository ships (configs/*.json) is read by the parser of its command
// (by name: dataset, reproduce and reproduce-*, *-meta for meta-train, the rest train), and
// every training config's backbone builds: a field renamed in the code, or a value edited by hand,
// fails here rather than hours into a run on a user's machine.
#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "pumeta/data/dataset.h"
#include "pumeta/eval/reproduce_config.h"
#include "pumeta/meta/meta_trainer.h"
#include "pumeta/models/backbone.h"
#include "pumeta/train/trainer.h"
#include "support/test_util.h"

namespace pumeta {
namespace {

namespace fs = std::filesystem;

std::vector<fs::path> shipped_configs() {
    std::vector<fs::path> files;
    for (const auto& entry : fs::directory_iterator(test::source_dir() + "/configs"))
        if (entry.path().extension() == ".json") files.push_back(entry.path());
    std::sort(files.begin(), files.end());
    return files;
}

bool ends_with(const std::string& s, const std::string& tail) {
    return s.size() >= tail.size() && s.compare(s.size() - tail.size(), tail.size(), tail) == 0;
}

TEST(ShippedConfigs, EachParsesWithItsCommandAndItsBackboneBuilds) {
    std::vector<fs::path> files = shipped_configs();
    // The training configs of six backbones, their meta-training configs, data, tables.
    ASSERT_GE(files.size(), 20u);
    int trains = 0, metas = 0;
    for (const fs::path& file : files) {
        SCOPED_TRACE(file.filename().string());
        const std::string name = file.stem().string();
        try {
            nlohmann::json j = nlohmann::json::parse(test::read_file(file.string()));
            if (name == "dataset") {
                DatasetConfig::from_json(j);
            } else if (name == "reproduce" || name.rfind("reproduce-", 0) == 0) {
                for (const char* budget : {"quick", "full"}) ReproduceConfig::from_json(j, budget);
            } else if (ends_with(name, "-meta")) {
                MetaTrainConfig::from_json(j);
                ++metas;
            } else {
                TrainConfig config = TrainConfig::from_json(j);
                EXPECT_NE(make_backbone(config.backbone), nullptr);
                ++trains;
            }
        } catch (const std::exception& error) {
            ADD_FAILURE() << error.what();
        }
    }
    EXPECT_GE(trains, 10);
    EXPECT_GE(metas, 5);
}

}  // namespace
}  // namespace pumeta
