#include "pumeta/models/downsample.h"

#include <ATen/ATen.h>

#include <random>
#include <vector>

#include "pumeta/core/error.h"
#include "pumeta/core/tensor_checks.h"
#include "pumeta/geometry/sampling.h"

namespace pumeta {

const char* downsampler_names() { return "fps, random, nonuniform"; }

void check_downsampler(const std::string& name, const std::string& context) {
    if (name != "fps" && name != "random" && name != "nonuniform")
        throw_input_error(context, "unknown downsampler '{}' (expected {})", name,
                          downsampler_names());
}

at::Tensor downsample_points(const at::Tensor& dense, int64_t m, const std::string& method,
                             uint64_t seed) {
    check_batched_points(dense, "downsample_points");
    check_downsampler(method, "downsample_points");
    const int64_t batch = dense.size(0), count = dense.size(1);
    if (m < 1 || m > count)
        throw_input_error("downsample_points", "cannot keep {} of {} points", m, count);
    at::NoGradGuard no_grad;
    at::Tensor indices;  // int64 [B,m]
    if (method == "fps") {
        indices = farthest_point_sampling_batched(dense.detach(), m);
    } else {
        std::mt19937_64 rng(seed);
        std::vector<at::Tensor> rows;
        for (int64_t b = 0; b < batch; ++b) {
            uint64_t element_seed = rng();
            if (method == "random") {
                rows.push_back(random_subset(count, m, element_seed));
                continue;
            }
            at::Tensor points = dense[b].detach().to(at::kCPU);
            int64_t centre = int64_t(rng() % uint64_t(count));
            at::Tensor by_distance = (points - points[centre]).pow(2).sum(-1).argsort();
            rows.push_back(by_distance.index_select(0, nonuniform_subset(count, m, element_seed)));
        }
        indices = at::stack(rows).to(dense.device());
    }
    return dense.gather(1, indices.unsqueeze(-1).expand({-1, -1, 3}));
}

}  // namespace pumeta
