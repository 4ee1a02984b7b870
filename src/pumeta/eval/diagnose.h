// Where a backbone's error on held-out patches comes from: its CD next to the decomposition the
// backbone reports in its own terms (Backbone::diagnose), averaged over a validation set.
#pragma once

#include <cstdint>
#include <nlohmann/json.hpp>

#include "pumeta/models/backbone.h"
#include "pumeta/train/validation.h"

namespace pumeta {

/// {"patches", "cd" (the model's mean CD), "input_cd", and the mean of every field of
/// model.diagnose() over the patches (NaN entries left out)}, evaluated `batch` patches at a time.
nlohmann::json diagnose_patches(const Backbone& model, const ValidationSet& set, int64_t batch = 8);

}  // namespace pumeta
