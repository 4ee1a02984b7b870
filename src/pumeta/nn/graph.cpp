#include "pumeta/nn/graph.h"

#include <ATen/ATen.h>
#include <ATen/Parallel.h>

#include <algorithm>
#include <cstring>
#include <limits>
#include <type_traits>
#include <utility>
#include <vector>

#include "pumeta/core/error.h"
#include "pumeta/core/tensor_checks.h"

namespace pumeta {

namespace {

void check_features(const at::Tensor& x, const char* what) {
    if (!x.defined() || x.dim() != 3 || !at::isFloatingType(x.scalar_type()))
        throw_input_error(what, "expected floating-point features of shape [B,N,C], found {}",
                          shape_string(x));
}

void check_graph(const at::Tensor& x, const at::Tensor& idx, const char* what) {
    check_features(x, what);
    if (!idx.defined() || idx.dim() != 3 || idx.scalar_type() != at::kLong ||
        idx.size(0) != x.size(0) || idx.size(1) != x.size(1) || idx.size(2) < 1)
        throw_input_error(what,
                          "expected int64 neighbour indices of shape [{}, {}, k>=1], found {}",
                          x.size(0), x.size(1), shape_string(idx));
}

// idx [B,N,k] into N -> flat indices into B*N rows.
at::Tensor flat_indices(const at::Tensor& idx, int64_t num_points) {
    at::Tensor offsets = at::arange(idx.size(0), idx.options()).mul_(num_points).view({-1, 1, 1});
    return (idx + offsets).view(-1);
}

// Running channel-wise maximum over the k candidate rows of each output row, keeping the
// winning candidate's slot j (first on ties). `candidate(row, j)` points at C values.
// Written so that the inner loop vectorises: same-width float/int32 selects, no branches.
template <typename scalar_t, typename Candidate>
void argmax_slots(int64_t rows, int64_t k, int64_t channels, Candidate candidate, int32_t* slots) {
    at::parallel_for(0, rows, 16, [&](int64_t begin, int64_t end) {
        std::vector<scalar_t> best(static_cast<size_t>(channels));
        for (int64_t row = begin; row < end; ++row) {
            int32_t* slot = slots + row * channels;
            const scalar_t* first = candidate(row, 0);
            for (int64_t c = 0; c < channels; ++c) {
                best[c] = first[c];
                slot[c] = 0;
            }
            for (int32_t j = 1; j < k; ++j) {
                const scalar_t* __restrict values = candidate(row, j);
                scalar_t* __restrict running = best.data();
                int32_t* __restrict winner = slot;
                for (int64_t c = 0; c < channels; ++c) {
                    scalar_t value = values[c], current = running[c];
                    using mask_t = std::conditional_t<sizeof(scalar_t) == 4, int32_t, int64_t>;
                    mask_t mask = -mask_t(value > current);  // all ones where larger
                    running[c] = current < value ? value : current;
                    winner[c] = int32_t((mask_t(j) & mask) | (mask_t(winner[c]) & ~mask));
                }
            }
        }
    });
}

void check_indices_in_range(const at::Tensor& idx, int64_t num_points, const char* what) {
    if (idx.numel() == 0) return;
    auto [lo, hi] = at::aminmax(idx);
    if (lo.item<int64_t>() < 0 || hi.item<int64_t>() >= num_points)
        throw_input_error(what, "neighbour indices [{}, {}] out of range [0, {})",
                          lo.item<int64_t>(), hi.item<int64_t>(), num_points);
}

// Float -> unsigned integer with the same order (negative floats flipped), so that a score
// and its index pack into one integer key.
inline uint32_t ordered_bits(float value) {
    uint32_t bits;
    std::memcpy(&bits, &value, sizeof bits);
    return (bits & 0x80000000u) ? ~bits : (bits | 0x80000000u);
}

// Moves the k smallest of `keys` (distinct, totally ordered) to its front, sorted. A threshold
// estimated from a sorted sample of every 8th key lets one branch-free pass keep only about
// k + 16 candidates, which are then sorted. For k = 20..40 of 256 this is about twice as fast
// as ATen's top-k, a heap (partial_sort) or nth_element + sort, whose branches mispredict.
// Falls back to nth_element when the estimate is too low.
template <typename Key>
void smallest_k_to_front(std::vector<Key>& keys, int64_t k, std::vector<Key>& candidates,
                         std::vector<Key>& sample) {
    constexpr int64_t kStride = 8;
    const int64_t n = int64_t(keys.size());
    sample.clear();
    for (int64_t j = 0; j < n; j += kStride) sample.push_back(keys[j]);
    std::sort(sample.begin(), sample.end());
    const int64_t pick =
        std::min<int64_t>(int64_t(sample.size()) - 1, (k + kStride - 1) / kStride + 1);
    const Key threshold = sample[pick];
    candidates.resize(keys.size());
    int64_t count = 0;
    for (int64_t j = 0; j < n; ++j) {
        candidates[count] = keys[j];
        count += !(threshold < keys[j]);
    }
    if (count >= k) {
        std::sort(candidates.begin(), candidates.begin() + count);
        std::copy(candidates.begin(), candidates.begin() + k, keys.begin());
    } else {
        std::nth_element(keys.begin(), keys.begin() + (k - 1), keys.end());
        std::sort(keys.begin(), keys.begin() + k);
    }
}

// The k smallest scores of each row of [R,N], sorted, ties by index.
template <typename scalar_t>
void smallest_k_cpu(const at::Tensor& scores, int64_t k, at::Tensor& out) {
    const int64_t n = scores.size(-1);
    const scalar_t* s = scores.data_ptr<scalar_t>();
    int64_t* result = out.data_ptr<int64_t>();
    // float32 (training): (score bits, index) packed in one uint64, compared in one instruction.
    using Key =
        std::conditional_t<std::is_same_v<scalar_t, float>, uint64_t, std::pair<scalar_t, int64_t>>;
    at::parallel_for(0, scores.numel() / n, 16, [&](int64_t begin, int64_t end) {
        std::vector<Key> keys(static_cast<size_t>(n)), candidates, sample;
        for (int64_t row = begin; row < end; ++row) {
            const scalar_t* values = s + row * n;
            for (int64_t j = 0; j < n; ++j) {
                if constexpr (std::is_same_v<scalar_t, float>)
                    keys[j] = (uint64_t(ordered_bits(values[j])) << 32) | uint64_t(j);
                else
                    keys[j] = {values[j], j};
            }
            smallest_k_to_front(keys, k, candidates, sample);
            for (int64_t j = 0; j < k; ++j) {
                if constexpr (std::is_same_v<scalar_t, float>)
                    result[row * k + j] = int64_t(keys[j] & 0xffffffffu);
                else
                    result[row * k + j] = keys[j].second;
            }
        }
    });
}

}  // namespace

at::Tensor knn_graph(const at::Tensor& features, int64_t k) {
    check_features(features, "knn_graph");
    const int64_t num_points = features.size(1);
    if (k < 1 || k >= num_points)
        throw_input_error("knn_graph", "k = {} must be in [1, N) with N = {}", k, num_points);
    at::NoGradGuard no_grad;
    at::Tensor x = features.detach();
    // |x_i - x_j|^2 = |x_i|^2 + |x_j|^2 - 2 x_i.x_j; |x_i|^2 is constant along each row, so
    // it cannot change the ranking and is left out.
    at::Tensor sq_norms = x.pow(2).sum(-1).unsqueeze(1).expand({-1, num_points, -1});
    at::Tensor scores = at::baddbmm(sq_norms, x, x.transpose(1, 2), /*beta=*/1, /*alpha=*/-2);
    scores.diagonal(0, 1, 2).fill_(std::numeric_limits<double>::infinity());
    if (!scores.device().is_cpu())
        return std::get<1>(scores.topk(k, -1, /*largest=*/false, /*sorted=*/true));
    at::Tensor out = at::empty({x.size(0), num_points, k}, x.options().dtype(at::kLong));
    AT_DISPATCH_FLOATING_TYPES(scores.scalar_type(), "knn_graph",
                               [&] { smallest_k_cpu<scalar_t>(scores, k, out); });
    return out;
}

at::Tensor gather_neighbors(const at::Tensor& x, const at::Tensor& idx) {
    check_graph(x, idx, "gather_neighbors");
    const int64_t batch = x.size(0), num_points = x.size(1), channels = x.size(2);
    at::Tensor rows = x.reshape({batch * num_points, channels});
    // Results are not views (like at::matmul's), so callers' in-place ops need no CopySlices.
    return at::_unsafe_view(rows.index_select(0, flat_indices(idx, num_points)),
                            {batch, num_points, idx.size(2), channels});
}

at::Tensor gather_max(const at::Tensor& x, const at::Tensor& idx) {
    check_graph(x, idx, "gather_max");
    const int64_t batch = x.size(0), num_points = x.size(1), channels = x.size(2);
    const int64_t k = idx.size(2);
    at::Tensor values = x.contiguous();
    at::Tensor flat;  // int64 [B,N,C]: position in `values` of each maximum
    {
        at::NoGradGuard no_grad;
        at::Tensor neighbors = idx.contiguous();
        at::Tensor slot;  // [B,N,C]: which of the k neighbours wins
        if (x.device().is_cpu()) {
            check_indices_in_range(neighbors, num_points, "gather_max");
            slot = at::empty(x.sizes(), idx.options().dtype(at::kInt));
            AT_DISPATCH_FLOATING_TYPES(x.scalar_type(), "gather_max", [&] {
                const scalar_t* xs = values.data_ptr<scalar_t>();
                const int64_t* is = neighbors.data_ptr<int64_t>();
                auto candidate = [&](int64_t row, int64_t j) {
                    return xs + ((row / num_points) * num_points + is[row * k + j]) * channels;
                };
                argmax_slots<scalar_t>(batch * num_points, k, channels, candidate,
                                       slot.data_ptr<int32_t>());
            });
            slot = slot.to(at::kLong);
        } else {
            slot = gather_neighbors(values.detach(), neighbors).argmax(2);
        }
        at::Tensor rows = neighbors.gather(2, slot) +
                          at::arange(batch, idx.options()).mul_(num_points).view({-1, 1, 1});
        flat = rows * channels + at::arange(channels, idx.options());
    }
    // Picking by flat position: index_select's backward is a 1-D index_add, cheaper than
    // gather's scatter.
    return at::_unsafe_view(values.view(-1).index_select(0, flat.view(-1)), x.sizes());
}

at::Tensor max_over_neighbors(const at::Tensor& y) {
    if (!y.defined() || y.dim() != 4 || y.size(2) < 1 || !at::isFloatingType(y.scalar_type()))
        throw_input_error("max_over_neighbors",
                          "expected floating-point edge features [B,N,k>=1,C], found {}",
                          shape_string(y));
    const int64_t rows = y.size(0) * y.size(1), k = y.size(2), channels = y.size(3);
    at::Tensor values = y.contiguous();
    at::Tensor flat;  // int64 [B,N,C]: position in `values` of each maximum
    {
        at::NoGradGuard no_grad;
        at::Tensor slot;  // [B,N,C]: which of the k edges wins
        if (y.device().is_cpu()) {
            slot = at::empty({y.size(0), y.size(1), channels}, y.options().dtype(at::kInt));
            AT_DISPATCH_FLOATING_TYPES(y.scalar_type(), "max_over_neighbors", [&] {
                const scalar_t* ys = values.data_ptr<scalar_t>();
                auto candidate = [&](int64_t row, int64_t j) {
                    return ys + (row * k + j) * channels;
                };
                argmax_slots<scalar_t>(rows, k, channels, candidate, slot.data_ptr<int32_t>());
            });
            slot = slot.to(at::kLong);
        } else {
            slot = values.argmax(2);
        }
        at::Tensor row_index = at::arange(rows, slot.options()).view({y.size(0), y.size(1), 1});
        flat = (row_index * k + slot) * channels + at::arange(channels, slot.options());
    }
    return at::_unsafe_view(values.view(-1).index_select(0, flat.view(-1)),
                            {y.size(0), y.size(1), channels});
}

}  // namespace pumeta
