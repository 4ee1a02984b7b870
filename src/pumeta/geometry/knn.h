// k-nearest-neighbour search: a kd-tree (nanoflann) for CPU tensors and a brute-force
// distance + topk path for GPU tensors. Both break ties by the smaller index and compute the
// same float32 distances, so they return bit-identical results.
#pragma once

#include <ATen/core/Tensor.h>

#include <cstdint>
#include <memory>

namespace pumeta {

/// Neighbours of Q queries, nearest first.
///   indices:      int64   [Q,k] (or [B,Q,k] for batched input)
///   sq_distances: float32 [Q,k] squared Euclidean distances (same shape)
struct KnnResult {
    at::Tensor indices;
    at::Tensor sq_distances;
};

/// A static kd-tree over float32 [N,3] points on the CPU. Build once, query many times.
/// Thread safety: query() is const and may be called from several threads at once; it also
/// parallelises internally over queries with ATen's intra-op thread pool.
class KdTree {
  public:
    /// points: float32 [N,3], 1 <= N < 2^32, any device. The tree keeps a contiguous CPU copy.
    explicit KdTree(const at::Tensor& points);
    ~KdTree();
    KdTree(KdTree&&) noexcept;
    KdTree& operator=(KdTree&&) noexcept;

    /// queries: float32 [Q,3] on the CPU; 1 <= k <= size(). Ties go to the smaller index.
    KnnResult query(const at::Tensor& queries, int64_t k) const;

    int64_t size() const;

  private:
    struct Impl;
    std::unique_ptr<Impl> impl_;
};

/// k nearest points of `points` for each query: points float32 [N,3] and queries [Q,3], or
/// batches [B,N,3] and [B,Q,3] (indices then count within each element). CPU tensors use
/// kd-trees (one per batch element, elements in parallel), others the brute force.
/// InputError when k is not in [1, N].
KnnResult knn(const at::Tensor& points, const at::Tensor& queries, int64_t k);

/// The indices of knn() for tensors of any floating type that autograd may track (a network's
/// coordinates): computed without gradient on float32 copies. The neighbour search of the
/// backbones' graphs.
at::Tensor knn_indices(const at::Tensor& points, const at::Tensor& queries, int64_t k);

/// Brute force on any device, same shapes as knn(). Processes queries in blocks to bound the
/// O(Q·N) distance matrix; no gradient flows into the result.
KnnResult knn_brute_force(const at::Tensor& points, const at::Tensor& queries, int64_t k);

}  // namespace pumeta
