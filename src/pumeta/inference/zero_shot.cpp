#include "pumeta/inference/zero_shot.h"

#include <ATen/ATen.h>

#include <algorithm>
#include <chrono>
#include <random>
#include <vector>

#include "pumeta/core/error.h"
#include "pumeta/core/tensor_checks.h"
#include "pumeta/geometry/patches.h"
#include "pumeta/geometry/sampling.h"
#include "pumeta/nn/adam.h"
#include "pumeta/nn/gradients.h"

namespace pumeta {

ZeroShotResult train_zero_shot(const nlohmann::json& architecture, const at::Tensor& cloud,
                               const ZeroShotOptions& options) {
    check_points(cloud, "zero-shot input", 1);
    if (options.steps < 1 || options.batch_patches < 1 || options.lr <= 0)
        throw_input_error("zero-shot", "steps, batch_patches and lr must be positive");
    auto start = std::chrono::steady_clock::now();
    nlohmann::json config = architecture;
    config["seed"] = options.seed;
    ZeroShotResult result;
    result.model = make_backbone(config);
    Backbone& model = *result.model;

    PatchOptions patch_options;
    patch_options.patch_size = model.patch_size();
    at::Tensor patches = extract_patches(cloud, patch_options).points;  // [P,n,3]
    int64_t num_patches = patches.size(0);

    Adam adam(model.parameters(), AdamOptions{options.lr});
    std::mt19937_64 rng(options.seed);
    std::uniform_int_distribution<int64_t> pick(0, num_patches - 1);
    std::vector<double> losses;
    for (int64_t step = 0; step < options.steps; ++step) {
        std::vector<at::Tensor> batch;
        for (int64_t b = 0; b < options.batch_patches; ++b) {
            at::Tensor patch = patches[pick(rng)];
            if (options.augment) patch = patch.matmul(random_rotation(rng));
            batch.push_back(patch);
        }
        at::Tensor x = at::stack(batch);
        at::Tensor x_down = model.downsample(x, options.seed * 1000003 + step);
        model.update_buffers(x_down, model.parameters());
        at::Tensor loss = model.loss(x_down, x, model.parameters(), step);
        adam.step(gradients(loss, model.parameters()));
        losses.push_back(loss.item<double>());
    }
    auto mean = [](auto begin, auto end) {
        double sum = 0;
        for (auto it = begin; it != end; ++it) sum += *it;
        return sum / std::max<std::ptrdiff_t>(1, end - begin);
    };
    int64_t window = std::min<int64_t>(10, losses.size());
    result.loss_first = mean(losses.begin(), losses.begin() + window);
    result.loss_last = mean(losses.end() - window, losses.end());
    result.seconds =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    return result;
}

}  // namespace pumeta
