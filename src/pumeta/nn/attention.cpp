#include "pumeta/nn/attention.h"

#include <ATen/ATen.h>

#include <algorithm>
#include <vector>

#include "pumeta/core/error.h"
#include "pumeta/core/tensor_checks.h"

namespace pumeta {

at::Tensor blocked_attention(const at::Tensor& q, const at::Tensor& k, const at::Tensor& v,
                             double scale, int64_t max_scores) {
    bool valid = q.defined() && k.defined() && v.defined() && q.dim() == 3 && k.dim() == 3 &&
                 v.dim() == 3 && q.size(0) == k.size(0) && k.size(0) == v.size(0) &&
                 q.size(2) == k.size(2) && k.size(1) == v.size(1) && k.size(1) >= 1 &&
                 q.is_floating_point() && q.scalar_type() == k.scalar_type() &&
                 k.scalar_type() == v.scalar_type();
    if (!valid)
        throw_input_error("blocked_attention",
                          "expected queries [B,M,D], keys [B,N,D], values [B,N,C] of one "
                          "floating type, found {}, {}, {}",
                          shape_string(q), shape_string(k), shape_string(v));
    if (max_scores < 1)
        throw_input_error("blocked_attention", "max_scores must be >= 1, found {}", max_scores);
    const int64_t rows = q.size(1);
    const int64_t block = std::max<int64_t>(1, max_scores / (q.size(0) * k.size(1)));
    at::Tensor keys_t = k.transpose(1, 2);
    auto attend = [&](const at::Tensor& queries) {
        return at::bmm(at::softmax(at::bmm(queries, keys_t).mul_(scale), -1), v);
    };
    if (block >= rows) return attend(q);
    std::vector<at::Tensor> parts;
    for (int64_t start = 0; start < rows; start += block)
        parts.push_back(attend(q.narrow(1, start, std::min(block, rows - start))));
    return at::cat(parts, 1);
}

}  // namespace pumeta
