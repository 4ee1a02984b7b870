// k-nearest-neighbour search: a kd-tree (nanoflann) for large CPU clouds and a brute-force
// cdist + topk path for small clouds, batches and GPU tensors.
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
    /// points: float32 [N,3], N >= 1. The tree keeps a contiguous copy.
    explicit KdTree(const at::Tensor& points);
    ~KdTree();
    KdTree(KdTree&&) noexcept;
    KdTree& operator=(KdTree&&) noexcept;

    /// queries: float32 [Q,3]; 1 <= k <= size(). Ties are broken by index.
    KnnResult query(const at::Tensor& queries, int64_t k) const;

    int64_t size() const;

  private:
    struct Impl;
    std::unique_ptr<Impl> impl_;
};

/// k nearest points of `points` [N,3] for each of `queries` [Q,3]; picks the kd-tree or brute
/// force by size and device. InputError when k > N.
KnnResult knn(const at::Tensor& points, const at::Tensor& queries, int64_t k);

/// Brute force on any device: points [N,3] or [B,N,3], queries [Q,3] or [B,Q,3].
/// Memory O(Q·N) per batch element; processes queries in chunks to bound it.
KnnResult knn_brute_force(const at::Tensor& points, const at::Tensor& queries, int64_t k);

}  // namespace pumeta
