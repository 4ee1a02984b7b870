// A bounding-volume hierarchy over triangles for exact closest-point queries.
#pragma once

#include <ATen/core/Tensor.h>

#include <memory>

#include "pumeta/geometry/point_cloud.h"

namespace pumeta {

class TriangleBvh {
  public:
    /// The mesh's faces must index its vertices; degenerate triangles are allowed.
    explicit TriangleBvh(const TriangleMesh& mesh);
    ~TriangleBvh();
    TriangleBvh(TriangleBvh&&) noexcept;
    TriangleBvh& operator=(TriangleBvh&&) noexcept;

    /// Unsquared distance from each query [Q,3] to the closest point on any triangle;
    /// returns float64 [Q]. Parallel over queries.
    at::Tensor distances(const at::Tensor& queries) const;

  private:
    struct Impl;
    std::unique_ptr<Impl> impl_;
};

/// Exact distance from point p to triangle (a, b, c) (Ericson, Real-Time Collision
/// Detection, 5.1.5). Exposed for tests.
double point_triangle_distance(const double p[3], const double a[3], const double b[3],
                               const double c[3]);

}  // namespace pumeta
