#include "pumeta/train/validation.h"

#include <ATen/ATen.h>

#include <numeric>

#include "pumeta/models/backbone.h"
#include "pumeta/nn/chamfer_loss.h"

namespace pumeta {

namespace {
constexpr int64_t kChunk = 32;
}

ValidationSet make_validation_set(const PatchSet& set, int64_t count, InputSampler sampler,
                                  uint64_t seed) {
    std::vector<int64_t> order(set.num_patches());
    std::iota(order.begin(), order.end(), 0);
    std::mt19937_64 rng(seed + 77);
    std::shuffle(order.begin(), order.end(), rng);
    count = std::min<int64_t>(count, set.num_patches());
    std::vector<at::Tensor> inputs, gts;
    for (int64_t i = 0; i < count; ++i) {
        Batch pair = make_pair(set.gt_patch(order[i]), set.patch_points, sampler, rng);
        inputs.push_back(pair.input);
        gts.push_back(pair.gt);
    }
    ValidationSet val{at::stack(inputs), at::stack(gts)};
    val.input_cd = mean_chamfer(val.input, val.gt);
    return val;
}

double mean_chamfer(const at::Tensor& a, const at::Tensor& b) {
    at::NoGradGuard no_grad;
    // chamfer_loss is 0.5·fwd + 0.5·bwd averaged over the batch: twice it is the CD.
    double total = 0;
    for (int64_t start = 0; start < a.size(0); start += kChunk) {
        int64_t end = std::min(a.size(0), start + kChunk);
        total += 2.0 * chamfer_loss(a.slice(0, start, end), b.slice(0, start, end)).item<double>() *
                 (end - start);
    }
    return total / a.size(0);
}

double validation_cd(const Backbone& model, const ValidationSet& set, const ParamMap* params) {
    at::NoGradGuard no_grad;
    std::vector<at::Tensor> outputs;
    for (int64_t start = 0; start < set.input.size(0); start += kChunk) {
        int64_t end = std::min(set.input.size(0), start + kChunk);
        outputs.push_back(
            model.upsample(set.input.slice(0, start, end), params ? *params : model.parameters()));
    }
    return mean_chamfer(at::cat(outputs), set.gt);
}

}  // namespace pumeta
