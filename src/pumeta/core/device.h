// --device plumbing: "cpu" or "cuda[:index]".
#pragma once

#include <string>

namespace pumeta {

/// Whether this build of LibTorch can see a CUDA device.
bool cuda_available();

/// Validates a device string; InputError for an unknown name or "cuda" without a GPU.
/// Returns the canonical form ("cpu", "cuda:0").
std::string parse_device(const std::string& device);

}  // namespace pumeta
