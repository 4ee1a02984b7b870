// Pictures of a make-dataset directory: what the network trains on and what it is tested on.
#pragma once

#include <cstdint>
#include <string>

#include "pumeta/render/render.h"

namespace pumeta {

struct ContactSheet {
    /// 16 training patches in a 4×4 grid, each GT patch (grey) with its input (orange).
    Image train_patches;
    /// Two cases of each test set the dataset holds at the ratio: input and GT side by side.
    Image test_cases;
};

/// The contact sheet of `dataset` at `ratio`; `seed` picks the patches and cases. InputError
/// when the training patch set of the ratio is missing.
ContactSheet make_contact_sheet(const std::string& dataset, int64_t ratio, uint64_t seed);

}  // namespace pumeta
