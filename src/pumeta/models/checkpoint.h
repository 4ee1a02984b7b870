// Checkpoints: a backbone's config and parameters (or any named tensors, e.g. optimiser state)
// with a JSON note, in one self-checking file.
//
// Format (version 1):
//   "PUMETA-CKPT\n"
//   one line of compact JSON: {"format_version": 1, "content": "backbone" | "tensors",
//     "config": <backbone config> (backbones only), "extra": <caller's JSON>,
//     "tensors": {name: {"dtype", "shape", "offset", "nbytes"}}, "payload_bytes": n,
//     "sha256": hex SHA-256 of (this header without "sha256", as compact JSON) + "\n" + payload}
//   the payload: every tensor's raw little-endian bytes, contiguous, in name order.
// A backbone's buffers (Backbone::buffers()) are stored as tensors named "buffers/<name>".
// The hash covers the header too, so no flipped byte anywhere goes unnoticed.
#pragma once

#include <memory>
#include <nlohmann/json.hpp>
#include <string>
#include <string_view>

#include "pumeta/models/backbone.h"
#include "pumeta/nn/parameters.h"

namespace pumeta {

/// Named tensors and the caller's JSON, as stored by save_tensors.
struct TensorFile {
    ParamMap tensors;
    nlohmann::json extra;
};

/// Writes `tensors` (any device; float32/64, int32/64, uint8 or bool) and `extra` to `path`
/// atomically (a temporary file in the same directory, then a rename). InputError when the
/// file cannot be written.
void save_tensors(const std::string& path, const ParamMap& tensors,
                  const nlohmann::json& extra = nlohmann::json::object());

/// Reads a file written by save_tensors (CPU tensors without requires_grad). InputError
/// "<path>: ..." for a missing, foreign, truncated or corrupted file or a backbone checkpoint.
TensorFile load_tensors(const std::string& path);

/// Writes the backbone's config and parameters with `extra` (e.g. the training step).
void save_checkpoint(const std::string& path, const Backbone& backbone,
                     const nlohmann::json& extra = nlohmann::json::object());

struct LoadedCheckpoint {
    std::unique_ptr<Backbone> backbone;
    nlohmann::json extra;
};

/// Rebuilds the backbone from the stored config (make_backbone) and loads its parameters.
/// InputError "<path>: ..." as load_tensors, and naming the tensor when the stored tensors do
/// not match the rebuilt backbone's names and shapes.
LoadedCheckpoint load_checkpoint(const std::string& path);

/// load_checkpoint on a file's bytes already in memory; `path` names it in messages.
LoadedCheckpoint parse_checkpoint(const std::string& path, std::string_view bytes);

}  // namespace pumeta
