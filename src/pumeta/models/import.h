// Released weights of other implementations as pumeta models (`pumeta import`): a state dict
// read from a torch.save archive (models/torch_archive.h), every tensor mapped by name onto a
// pumeta backbone with shape checks.
#pragma once

#include <memory>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "pumeta/models/backbone.h"
#include "pumeta/models/torch_archive.h"

namespace pumeta {

/// The formats import_weights reads: "gradpu" (yunhe20/Grad-PU's P2PNet state dict) and
/// "pugaussian" (mvg-inatech/PU-Gaussian's PU_Gaussian state dict; its unused feature
/// projection and confidence head are skipped).
std::vector<std::string> import_formats();

/// `dict`, read from `path`, as a backbone of format `format` built from `config` (the kind's
/// options; the format's defaults where a field is absent). Every tensor of the file must map
/// onto one of the backbone (batch-norm step counters aside) and every parameter and buffer
/// of the backbone must be filled, with the same shape up to the trailing 1s of a convolution
/// kernel. InputError "<path>: ..." naming the tensor otherwise, or for an unknown format.
std::unique_ptr<Backbone> import_state_dict(
    const std::string& format, const StateDict& dict, const std::string& path,
    const nlohmann::json& config = nlohmann::json::object());

/// read_torch_state_dict(path) then import_state_dict.
std::unique_ptr<Backbone> import_weights(const std::string& format, const std::string& path,
                                         const nlohmann::json& config = nlohmann::json::object());

}  // namespace pumeta
