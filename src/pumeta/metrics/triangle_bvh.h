// A bounding-volume hierarchy over triangles for exact closest-point queries and first-hit
// ray casting.
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

    /// Distance along the ray origin + t·direction (direction need not be unit; t is then in
    /// its units) to the first triangle it crosses with 0 < t <= max_t, either side facing (a ray
    /// through a shared edge hits); +infinity when there is none. Degenerate triangles are never
    /// hit.
    double first_hit(const double origin[3], const double direction[3], double max_t) const;

    /// first_hit for each ray: origins and directions float32 or float64 [Q,3] (the same Q;
    /// else InputError); returns a float64 CPU tensor [Q]. Parallel over rays.
    at::Tensor first_hits(const at::Tensor& origins, const at::Tensor& directions,
                          double max_t) const;

  private:
    struct Impl;
    std::unique_ptr<Impl> impl_;
};

/// Exact (unsquared) distance from point p to triangle (a, b, c), each a double[3]
/// (Ericson, Real-Time Collision Detection, 5.1.5). Exposed for tests.
double point_triangle_distance(const double p[3], const double a[3], const double b[3],
                               const double c[3]);

}  // namespace pumeta
