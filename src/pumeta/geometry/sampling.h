// Sampling points: from clouds (farthest point, uniform random, the PU-GAN non-uniform
// index sampler) and from meshes (area-weighted uniform, Poisson disk by sample elimination).
// Every random function takes a seed; the same seed gives the same result.
#pragma once

#include <ATen/core/Tensor.h>

#include <cstdint>
#include <random>

#include "pumeta/geometry/point_cloud.h"

namespace pumeta {

/// Farthest point sampling. points: float32 [N,3]; returns int64 [m] indices (on the points'
/// device; computed on the CPU), the first being `start` (the point itself, not a random choice,
/// so results are reproducible). Ties go to the smaller index; once only duplicates of chosen
/// points remain, indices may repeat. InputError when m > N.
at::Tensor farthest_point_sampling(const at::Tensor& points, int64_t m, int64_t start = 0);

/// farthest_point_sampling()'s answer by a k-d tree that skips the regions a pick cannot
/// change: about N·log(m) distance updates instead of N·m once the picks are dense, on one
/// thread. InputError also for non-finite coordinates.
at::Tensor farthest_point_sampling_pruned(const at::Tensor& points, int64_t m, int64_t start = 0);

/// Batched FPS on any device: points float32/float64 [B,N,3] -> int64 [B,m], starting at
/// index 0 of each; the same answer as farthest_point_sampling() per element. float32 CPU
/// input runs the CPU loop (elements in parallel), anything else tensor ops.
at::Tensor farthest_point_sampling_batched(const at::Tensor& points, int64_t m);

/// Indices (ascending) of the first occurrence of every distinct point of float32 [N,3]
/// `points` that does not also occur in float32 [K,3] `exclude` (K may be 0): the rows a
/// selection may pick without ever returning one position twice. Points are equal when their
/// coordinates are (0 and -0 alike). O(N + K) expected time.
at::Tensor distinct_points(const at::Tensor& points, const at::Tensor& exclude = {});

/// The number of distinct positions among float32 [N,3] points.
int64_t count_distinct_points(const at::Tensor& points);

/// n points uniform in the cube [-1, 1]³, float32 [n,3], from mt19937_64(seed): the synthetic
/// clouds of the tests and benchmarks.
at::Tensor uniform_random_points(int64_t n, uint64_t seed);

/// m distinct indices drawn uniformly from [0, n) (sorted ascending). InputError when m > n.
at::Tensor random_subset(int64_t n, int64_t m, uint64_t seed);

/// A uniformly random rotation matrix, float32 [3,3] (Shoemake's random unit quaternion).
at::Tensor random_rotation(std::mt19937_64& rng);

/// The PU-GAN/PU-GCN non-uniform index sampler: loc ~ U(0.1, 0.9); draw
/// int(N(loc, 0.3) * n) until m unique indices in [0, n) are found; returns int64 [m] in
/// draw order. The points must be ordered spatially (e.g. by distance to a patch seed) for
/// the result to be non-uniform on the surface.
at::Tensor nonuniform_subset(int64_t n, int64_t m, uint64_t seed);

/// n points uniformly distributed on the surface (triangle chosen by area, uniform
/// barycentrics), with the face normals. Degenerate (zero-area) faces are never chosen.
PointCloud sample_uniform(const TriangleMesh& mesh, int64_t n, uint64_t seed);

/// Indices (ascending) of the n of float32 [M,3] `points` that weighted sample elimination
/// keeps (Yuksel 2015): repeatedly drops the point with the largest weight
/// sum(1 - d / 2 r_max)^8 over neighbours closer than 2 r_max (ties: larger index first).
/// r_max is the Poisson-disk radius of n points on the sampled surface, 2 sqrt(A / n / (2 sqrt 3))
/// for area A. O(M log M) time and O(M) memory.
at::Tensor eliminate_samples(const at::Tensor& points, int64_t n, double r_max);

/// Options of Poisson-disk sampling by weighted sample elimination (Yuksel 2015), the method
/// of Open3D's SamplePointsPoissonDisk.
struct PoissonDiskOptions {
    /// Initial uniform samples = init_factor * n (Open3D's default 5).
    int64_t init_factor = 5;
};

/// n blue-noise points on the surface with face normals: the candidates
/// sample_uniform(mesh, init_factor * n, seed), thinned by repeatedly eliminating the one with
/// the largest weight sum(1 - d / 2 r_max)^8 over neighbours closer than 2 r_max, where
/// r_max = 2 sqrt(area / n / (2 sqrt 3)) (ties: larger index first). The survivors keep the
/// candidates' order. O(M log M) time and O(M) memory for M candidates.
PointCloud sample_poisson_disk(const TriangleMesh& mesh, int64_t n, uint64_t seed,
                               const PoissonDiskOptions& options = {});

}  // namespace pumeta
