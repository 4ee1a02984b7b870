#include "pumeta/models/pugcn.h"

#include <ATen/ATen.h>

#include <random>

#include "pumeta/core/error.h"
#include "pumeta/core/tensor_checks.h"
#include "pumeta/models/config_fields.h"
#include "pumeta/models/downsample.h"
#include "pumeta/nn/chamfer_loss.h"
#include "pumeta/nn/conv.h"
#include "pumeta/nn/dense_gcn.h"
#include "pumeta/nn/graph.h"
#include "pumeta/nn/init.h"
#include "pumeta/nn/periodic_shuffle.h"

namespace pumeta {

namespace {

constexpr const char* kContext = "pugcn config";

template <class Self, class Visit>
void visit_fields(Self& o, Visit&& visit) {
    visit("ratio", o.ratio, field::positive_int);
    visit("channels", o.channels, field::positive_int);
    visit("blocks", o.blocks, field::positive_int);
    visit("k", o.k, field::positive_int);
    visit("dilation", o.dilation, field::positive_int);
    visit("upsample_channels", o.upsample_channels, field::positive_int);
    visit("reconstruction_channels", o.reconstruction_channels, field::positive_int);
    visit("patch_size", o.patch_size, field::positive_int);
    visit("downsampler", o.downsampler, field::downsampler);
    visit("loss_scale", o.loss_scale, field::positive_number);
    visit("seed", o.seed, field::seed);
}

std::string block_prefix(int64_t block) { return "block" + std::to_string(block); }

}  // namespace

PuGcnOptions PuGcnOptions::from_json(const nlohmann::json& config) {
    PuGcnOptions options;
    read_backbone_config(config, "pugcn", [&](auto&& visit) { visit_fields(options, visit); });
    if (options.k * options.dilation >= options.patch_size)
        throw_input_error(kContext, "k·dilation = {} needs patches of more points than {}",
                          options.k * options.dilation, options.patch_size);
    return options;
}

nlohmann::json PuGcnOptions::to_json() const {
    return write_backbone_config("pugcn", [&](auto&& visit) { visit_fields(*this, visit); });
}

PuGcn::PuGcn(const PuGcnOptions& options) : options_(options) {
    std::mt19937_64 rng(options.seed);
    const int64_t width = options.channels;
    // Two DenseGCN paths of 3·width channels plus the 1-channel global pooling path.
    const int64_t block_channels = 6 * width + 1;
    add_edge_conv(params_, "head", 3, width, rng);
    int64_t in = width;
    for (int64_t b = 0; b < options.blocks; ++b) {
        add_linear(params_, block_prefix(b) + ".reduction", in, width, /*bias=*/true, rng);
        add_dense_gcn(params_, block_prefix(b) + ".path1", width, width, rng);
        add_dense_gcn(params_, block_prefix(b) + ".path2", width, width, rng);
        in = block_channels;
    }
    const int64_t up = options.upsample_channels;
    add_linear(params_, "up.reduction", block_channels, up, /*bias=*/true, rng);
    add_edge_conv(params_, "up.edge", up, up * options.ratio, rng);
    add_linear(params_, "out.fc1", up, options.reconstruction_channels, /*bias=*/true, rng);
    add_linear(params_, "out.fc2", options.reconstruction_channels, 3, /*bias=*/true, rng);
}

at::Tensor PuGcn::upsample(const at::Tensor& x, const ParamMap& params) const {
    check_batched_points(x, "pugcn input");
    const int64_t batch = x.size(0), num_points = x.size(1), r = options_.ratio;
    const int64_t dilation = options_.dilation;
    if (num_points < 2)
        throw_input_error("pugcn input", "needs at least 2 points per patch, found {}", num_points);
    // Patches smaller than the graphs need (tiny inputs; X↓ of a 256-point patch at 8x and
    // 16x) use as many neighbours as exist: the weights do not depend on k.
    const int64_t k = std::min(options_.k, num_points - 1);
    const int64_t k_dilated = std::min(options_.k * dilation, num_points - 1);
    const at::Tensor& head = param(params, "head.central.weight");
    if (head.scalar_type() != x.scalar_type() || head.device() != x.device())
        throw_input_error("pugcn input", "points are {} on {}, parameters {} on {}",
                          std::string(c10::toString(x.scalar_type())), x.device().str(),
                          std::string(c10::toString(head.scalar_type())), head.device().str());

    // Feature extraction: the xyz graph idx0 is reused by NodeShuffle.
    at::Tensor xyz_graph = knn_graph(x, k);
    at::Tensor features = edge_conv(x, xyz_graph, params, "head");
    at::Tensor fused;
    for (int64_t b = 0; b < options_.blocks; ++b) {
        const std::string prefix = block_prefix(b);
        at::Tensor graph = knn_graph(features, k_dilated);
        at::Tensor nearest = graph.narrow(2, 0, k);
        at::Tensor dilated = graph.slice(2, 0, k_dilated, dilation);
        at::Tensor reduced = at::relu(conv1x1(features, params, prefix + ".reduction"));
        at::Tensor out = at::cat({dense_gcn(reduced, nearest, params, prefix + ".path1"),
                                  dense_gcn(reduced, dilated, params, prefix + ".path2"),
                                  features.amax(-1, /*keepdim=*/true)},
                                 -1);
        if (out.size(-1) == features.size(-1)) out = out + features;
        features = out;
        fused = b == 0 ? features : fused + features;
    }
    fused = fused / double(options_.blocks);

    // NodeShuffle: r·C channels per point on the xyz graph, shuffled into r points.
    at::Tensor up = at::relu(conv1x1(fused, params, "up.reduction"));
    up = periodic_shuffle(edge_conv(up, xyz_graph, params, "up.edge"), r);

    // Coordinate reconstruction, as offsets from the input point each output came from.
    at::Tensor offsets =
        conv1x1(at::leaky_relu(conv1x1(up, params, "out.fc1"), 0.2), params, "out.fc2");
    return offsets + x.unsqueeze(2).expand({batch, num_points, r, 3}).reshape({batch, -1, 3});
}

at::Tensor PuGcn::loss(const at::Tensor& input, const at::Tensor& target, const ParamMap& params,
                       int64_t step) const {
    return options_.loss_scale * chamfer_loss(upsample(input, params), target);
}

at::Tensor PuGcn::downsample(const at::Tensor& dense, uint64_t seed) const {
    check_batched_points(dense, "pugcn downsample");
    return downsample_points(dense, dense.size(1) / options_.ratio, options_.downsampler, seed);
}

std::unique_ptr<Backbone> make_pugcn(const nlohmann::json& config) {
    return std::make_unique<PuGcn>(PuGcnOptions::from_json(config));
}

nlohmann::json pugcn_small_config() {
    return {{"backbone", "pugcn"},
            {"ratio", 4},
            {"channels", 4},
            {"k", 4},
            {"dilation", 2},
            {"upsample_channels", 4},
            {"reconstruction_channels", 4},
            {"patch_size", 16},
            {"downsampler", "random"},
            {"seed", 3}};
}

}  // namespace pumeta
