// A bounding-volume hierarchy over triangles for exact closest-point queries.
#pragma once

#include <ATen/core/Tensor.h>

#include <memory>

#include "pumeta/geometry/point_cloud.h"

namespace pumeta {

class TriangleBvh {
  public:
    /// mesh.vertices: float32 [V,3], V >= 1; mesh.faces: int64 [F,3], each index in [0, V)
    /// (else InputError). Degenerate triangles are allowed.
    explicit TriangleBvh(const TriangleMesh& mesh);
    ~TriangleBvh();
    TriangleBvh(TriangleBvh&&) noexcept;
    TriangleBvh& operator=(TriangleBvh&&) noexcept;

    /// Unsquared distance from each query (float32 [Q,3], Q >= 0; else InputError) to the
    /// closest point on any triangle; returns a float64 CPU tensor [Q]. Parallel over queries.
    at::Tensor distances(const at::Tensor& queries) const;

  private:
    struct Impl;
    std::unique_ptr<Impl> impl_;
};

/// Exact (unsquared) distance from point p to triangle (a, b, c), each a double[3]
/// (Ericson, Real-Time Collision Detection, 5.1.5). Exposed for tests.
double point_triangle_distance(const double p[3], const double a[3], const double b[3],
                               const double c[3]);

}  // namespace pumeta
