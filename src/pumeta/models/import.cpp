#include "pumeta/models/import.h"

#include <ATen/ATen.h>

#include <functional>
#include <map>
#include <set>

#include "pumeta/core/error.h"
#include "pumeta/core/tensor_checks.h"
#include "pumeta/models/gradpu.h"
#include "pumeta/models/pugaussian.h"

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

/// PU-Gaussian's PU_Gaussian module (model/models.py, GaussianNetwork.py, PUCRN.py).
NameMap pugaussian_names() {
    NameMap names;
    auto two_layers = [&](const std::string& to, const std::string& from, const char* second) {
        map_conv(names, to + ".0", from + ".0", false);
        map_conv(names, to + ".1", from + "." + second, false);
    };
    // nn.Sequential(Conv2d, BatchNorm2d, ReLU, Conv2d) of the position and attention MLPs.
    auto norm_mlp = [&](const std::string& to0, const std::string& to1, const std::string& from) {
        map_conv(names, to0, from + ".0", false);
        names[to0 + ".bn.gamma"] = from + ".1.weight";
        names[to0 + ".bn.beta"] = from + ".1.bias";
        names[to0 + ".bn.running_mean"] = from + ".1.running_mean";
        names[to0 + ".bn.running_var"] = from + ".1.running_var";
        map_conv(names, to1, from + ".3", false);
    };
    auto transformer = [&](const std::string& to, const std::string& from) {
        map_conv(names, to + ".start", from + ".linear_start", false);
        map_conv(names, to + ".end", from + ".linear_end", false);
        for (const char* name : {"query", "key", "value"})
            map_conv(names, to + "." + name, from + ".conv_" + name, false);
        norm_mlp(to + ".pos0", to + ".pos1", from + ".pos_mlp");
        norm_mlp(to + ".attn0", to + ".attn1", from + ".attn_mlp");
    };
    const std::string gaussian = "Gaussian.feature_extractor";
    two_layers("gaussian.mlp1", gaussian + ".extractor.mlp_1.mlp", "2");
    two_layers("gaussian.mlp2", gaussian + ".extractor.mlp_2.mlp", "2");
    transformer("gaussian.transformer", gaussian + ".extractor.point_transformer");
    two_layers("gaussian.offset", gaussian + ".mean_head", "2");
    two_layers("gaussian.scale", gaussian + ".scale_head", "2");
    two_layers("gaussian.rotation", gaussian + ".rot_head", "2");
    const std::string refine = "refinement";
    two_layers("refine.mlp1", refine + ".feature_extractor.mlp_1.mlp", "2");
    two_layers("refine.mlp2", refine + ".feature_extractor.mlp_2.mlp", "2");
    transformer("refine.transformer", refine + ".feature_extractor.point_transformer");
    two_layers("refine.up.mlp", refine + ".up_unit.mlp_1.mlp", "2");
    names["refine.up.deconv.weight"] = refine + ".up_unit.deconv_branch.weight";
    map_conv(names, "refine.up.res.conv1", refine + ".up_unit.mlp_2.conv_1", false);
    map_conv(names, "refine.up.res.conv2", refine + ".up_unit.mlp_2.conv_2", false);
    map_conv(names, "refine.up.res.shortcut", refine + ".up_unit.mlp_2.conv_shortcut", false);
    two_layers("refine.regressor", refine + ".regressor.mlp", "2");
    return names;
}

/// Tensors of a PU-Gaussian file that feed nothing: a feature projection its forward pass
/// never calls and the confidence head, whose output is discarded.
bool pugaussian_unused(const std::string& name) {
    for (const char* prefix : {"Gaussian.feature_extractor.extractor.mlp_proj.",
                               "Gaussian.feature_extractor.confidence_head."})
        if (name.rfind(prefix, 0) == 0) return true;
    return false;
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

std::vector<std::string> import_formats() { return {"gradpu", "pugaussian"}; }

std::unique_ptr<Backbone> import_state_dict(const std::string& format, const StateDict& dict,
                                            const std::string& path, const nlohmann::json& config) {
    nlohmann::json full = config;
    full["backbone"] = format;
    std::unique_ptr<Backbone> model;
    NameMap names;
    std::function<bool(const std::string&)> unused = [](const std::string&) { return false; };
    if (format == "gradpu") {
        auto gradpu = std::make_unique<GradPu>(GradPuOptions::from_json(full));
        names = gradpu_names(gradpu->options());
        model = std::move(gradpu);
    } else if (format == "pugaussian") {
        model = std::make_unique<PuGaussian>(PuGaussianOptions::from_json(full));
        names = pugaussian_names();
        unused = pugaussian_unused;
    } else {
        throw_input_error("--from", "unknown format '{}' (known: gradpu, pugaussian)", format);
    }
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
        if (!used.count(name) && !counter && !unused(name))
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
