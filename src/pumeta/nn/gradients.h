// Gradients of a scalar with respect to a ParamMap, keeping names.
#pragma once

#include <ATen/core/Tensor.h>

#include "pumeta/nn/parameters.h"

namespace pumeta {

/// d loss / d wrt[name] for every name of `wrt`. With create_graph the gradients are part of
/// the graph (second-order MAML); otherwise they are detached. Parameters the loss does not
/// depend on get zero gradients.
ParamMap gradients(const at::Tensor& loss, const ParamMap& wrt, bool create_graph = false,
                   bool retain_graph = false);

/// The detached gradients of the parameters of `wrt` that the loss depends on; the others are
/// absent, so that Adam leaves them and their moments untouched (levels a curriculum keeps
/// out of a step).
ParamMap used_gradients(const at::Tensor& loss, const ParamMap& wrt);

}  // namespace pumeta
