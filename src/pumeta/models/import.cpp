#include "pumeta/models/import.h"

#include <ATen/ATen.h>

#include <map>
#include <set>

#include "pumeta/core/error.h"
#include "pumeta/core/tensor_checks.h"
#include "pumeta/models/gradpu.h"

namespace pumeta {

namespace {

/// pumeta's name of a parameter or buffer -> the original's.
using NameMap = std::map<std::string, std::string>;

/// A convolution with bias and (with `norm`) the BatchNorm after it, as an nn.Sequential of
/// (Conv, BatchNorm, ReLU) in the original: `to` ← `from`.0 and `to`.bn ← `from`.1.
void map_conv(NameMap& names, const std::string& to, const std::string& from, bool norm) {
    const std::string conv = norm ? from + ".0" : from;
    names[to + ".weight"] = conv + ".weight";
    names[to + ".bias"] = conv + ".bias";
    if (!norm) return;
    names[to + ".bn.gamma"] = from + ".1.weight";
    names[to + ".bn.beta"] = from + ".1.bias";
    names[to + ".bn.running_mean"] = from + ".1.running_mean";
    names[to + ".bn.running_var"] = from + ".1.running_var";
}

/// Grad-PU's P2PNet (models/FeatureExtractor.py, models/P2PRegressor.py).
NameMap gradpu_names(const GradPuOptions& o) {
    NameMap names;
    map_conv(names, "extractor.init", "feature_extractor.conv_init", true);
    for (int64_t b = 0; b < o.blocks; ++b) {
        const std::string block = "feature_extractor.dense_blocks." + std::to_string(b);
        for (int64_t l = 0; l < o.layers; ++l) {
            const std::string to =
                "extractor.block" + std::to_string(b) + ".layer" + std::to_string(l);
            const std::string from = block + ".0.dense_layers." + std::to_string(l);
            map_conv(names, to + ".bottle", from + ".conv_bottle", true);
            map_conv(names, to + ".delta", from + ".point_conv.conv_delta", true);
            map_conv(names, to + ".feats", from + ".point_conv.conv_feats", true);
            map_conv(names, to + ".post", from + ".point_conv.post_conv", true);
        }
        map_conv(names, "extractor.block" + std::to_string(b) + ".transition", block + ".1.trans",
                 true);
    }
    for (int i = 0; i < 4; ++i)
        map_conv(names, "regressor.mlp" + std::to_string(i),
                 "p2p_regressor.mlp_" + std::to_string(i), false);
    return names;
}

/// `source` without the trailing 1s a convolution kernel adds ([O,I,1] or [O,I,1,1] for a
/// pumeta [O,I]), when that gives `shape`.
at::Tensor fitted(const at::Tensor& source, at::IntArrayRef shape) {
    at::Tensor t = source;
    while (t.dim() > static_cast<int64_t>(shape.size()) && t.size(-1) == 1) t = t.squeeze(-1);
    return t.sizes() == shape ? t : at::Tensor();
}

void fill(ParamMap& targets, const NameMap& names, const std::map<std::string, at::Tensor>& source,
          std::set<std::string>& used, const std::string& path, bool trainable) {
    for (auto& [name, tensor] : targets) {
        auto original = names.find(name);
        if (original == names.end()) throw InternalError("import: no original name for " + name);
        auto found = source.find(original->second);
        if (found == source.end())
            throw_input_error(path, "has no tensor {} (for {})", original->second, name);
        if (found->second.scalar_type() != at::kFloat)
            throw_input_error(path, "tensor {} is {}, not float32", original->second,
                              std::string(c10::toString(found->second.scalar_type())));
        at::Tensor value = fitted(found->second, tensor.sizes());
        if (!value.defined())
            throw_input_error(path, "tensor {} has shape {}, {} needs {}", original->second,
                              shape_string(found->second), name, shape_string(tensor));
        at::Tensor copy = value.to(tensor.device()).contiguous().clone();
        tensor = trainable ? copy.requires_grad_(true) : copy;
        used.insert(original->second);
    }
}

}  // namespace

std::vector<std::string> import_formats() { return {"gradpu"}; }

std::unique_ptr<Backbone> import_state_dict(const std::string& format, const StateDict& dict,
                                            const std::string& path, const nlohmann::json& config) {
    if (format != "gradpu")
        throw_input_error("--from", "unknown format '{}' (known: gradpu)", format);
    nlohmann::json full = config;
    full["backbone"] = "gradpu";
    auto model = std::make_unique<GradPu>(GradPuOptions::from_json(full));
    const NameMap names = gradpu_names(model->options());
    std::map<std::string, at::Tensor> source;
    for (const auto& [name, tensor] : dict)
        if (!source.emplace(name, tensor).second)
            throw_input_error(path, "holds tensor {} twice", name);
    std::set<std::string> used;
    fill(model->parameters(), names, source, used, path, /*trainable=*/true);
    fill(model->buffers(), names, source, used, path, /*trainable=*/false);
    for (const auto& [name, tensor] : dict) {
        const std::string suffix = ".num_batches_tracked";
        const bool counter = name.size() > suffix.size() &&
                             name.compare(name.size() - suffix.size(), suffix.size(), suffix) == 0;
        if (!used.count(name) && !counter)
            throw_input_error(path,
                              "tensor {} belongs to no part of a {} network; is this a {} "
                              "checkpoint?",
                              name, format, format);
    }
    return model;
}

std::unique_ptr<Backbone> import_weights(const std::string& format, const std::string& path,
                                         const nlohmann::json& config) {
    return import_state_dict(format, read_torch_state_dict(path), path, config);
}

}  // namespace pumeta
