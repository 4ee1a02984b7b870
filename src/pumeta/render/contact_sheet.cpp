#include "pumeta/render/contact_sheet.h"

#include <ATen/ATen.h>

#include <filesystem>
#include <random>

#include "pumeta/data/layout.h"
#include "pumeta/data/patch_set.h"
#include "pumeta/geometry/io.h"

namespace pumeta {

namespace fs = std::filesystem;

namespace {

/// GT (grey) with the input on top (orange), as one coloured cloud.
Image render_pair(const at::Tensor& input, const at::Tensor& gt, const RenderOptions& base) {
    RenderOptions options = base;
    options.frame = fit_frame(gt);
    at::Tensor points = at::cat({gt, input});
    at::Tensor colors = at::cat({at::full({gt.size(0), 3}, 0.7f),
                                 at::tensor({0.95f, 0.45f, 0.1f}).expand({input.size(0), 3})});
    return render_image(points, options, colors);
}

}  // namespace

ContactSheet make_contact_sheet(const std::string& dataset, int64_t ratio, uint64_t seed) {
    ContactSheet sheet;
    RenderOptions options;
    options.width = options.height = 256;
    std::mt19937_64 rng(seed);

    PatchSet train = load_patch_set(layout::patch_set_path(dataset, "train", ratio).string());
    std::vector<Image> patches;
    std::vector<std::string> labels;
    for (int i = 0; i < 16; ++i) {
        int64_t s = std::uniform_int_distribution<int64_t>(0, train.num_patches() - 1)(rng);
        Batch pair = make_pair(train.gt_patch(s), train.patch_points, InputSampler::kFps, rng);
        patches.push_back(render_pair(pair.input, pair.gt, options));
        labels.push_back(train.ids[train.seeds[s][0].item<int64_t>()]);
    }
    sheet.train_patches = render_grid(patches, 4, labels);

    std::vector<Image> cases;
    std::vector<std::string> case_labels;
    // Not kTestSets' order: the picks of the seeded generator follow this one.
    for (const char* set :
         {layout::kTestIndist, layout::kTestScans, layout::kTestHumans, layout::kTestAerial}) {
        fs::path dir = layout::cases_dir(dataset, set, ratio);
        if (!fs::exists(layout::case_index_path(dir))) continue;
        nlohmann::json list = layout::read_case_index(dir)["cases"];
        for (int i = 0; i < 2 && !list.empty(); ++i) {
            auto pick = std::uniform_int_distribution<size_t>(0, list.size() - 1)(rng);
            fs::path c = dir / list[pick]["name"].get<std::string>();
            at::Tensor input = read_point_cloud((c / layout::kInputFile).string()).points;
            at::Tensor gt = read_point_cloud((c / layout::kGtFile).string()).points;
            RenderOptions o = options;
            o.frame = fit_frame(gt);
            cases.push_back(render_image(input, o));
            cases.push_back(render_image(gt, o));
            case_labels.push_back(std::string(set) + ": input");
            case_labels.push_back(list[pick]["id"].get<std::string>() + ": GT");
            list.erase(list.begin() + static_cast<std::ptrdiff_t>(pick));
        }
    }
    sheet.test_cases = render_grid(cases, 4, case_labels);
    return sheet;
}

}  // namespace pumeta
