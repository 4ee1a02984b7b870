#include "pumeta/nn/periodic_shuffle.h"

#include <ATen/ATen.h>

#include "pumeta/core/error.h"
#include "pumeta/core/tensor_checks.h"

namespace pumeta {

at::Tensor periodic_shuffle(const at::Tensor& x, int64_t r) {
    if (!x.defined() || x.dim() != 3 || r < 1 || x.size(2) % r != 0)
        throw_input_error("periodic_shuffle",
                          "expected features [B,N,C*r] with r = {} dividing the channels, found {}",
                          r, shape_string(x));
    const int64_t batch = x.size(0), num_points = x.size(1), channels = x.size(2) / r;
    return x.view({batch, num_points, channels, r})
        .transpose(2, 3)
        .reshape({batch, num_points * r, channels});
}

}  // namespace pumeta
