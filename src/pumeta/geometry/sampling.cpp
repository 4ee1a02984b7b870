#include "pumeta/geometry/sampling.h"

#include <ATen/ATen.h>
#include <ATen/Parallel.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <numeric>
#include <optional>
#include <random>
#include <unordered_set>
#include <vector>

#include "pumeta/core/error.h"
#include "pumeta/core/tensor_checks.h"

namespace pumeta {

namespace {

/// Points per parallel task: FPS enters the thread pool once per selected point, so each task
/// must do enough work (some 10 us of distance updates) to pay for the hand-off.
constexpr int64_t kFpsChunk = 16384;

/// The farthest point of one chunk; ties go to the smaller index, as in a sequential scan.
struct Farthest {
    float sq_distance = -1.f;
    int64_t index = -1;
};

/// Four floats in one vector register (GCC's and Clang's vector extension: SSE on x86-64,
/// NEON on ARM); the distance update runs on kFpsVectors of them at a time.
using Float4 = float __attribute__((vector_size(16)));
constexpr int kFpsVectors = 2;
constexpr int64_t kFpsLanes = 4 * kFpsVectors;

Float4 load4(const float* p) {
    Float4 v;
    std::memcpy(&v, p, sizeof v);
    return v;
}

/// The coordinates as three arrays, so that the distance update reads each axis contiguously.
struct AxisArrays {
    std::vector<float> x, y, z;

    AxisArrays(const float* xyz, int64_t n) : x(n), y(n), z(n) {
        for (int64_t j = 0; j < n; ++j) {
            x[j] = xyz[3 * j];
            y[j] = xyz[3 * j + 1];
            z[j] = xyz[3 * j + 2];
        }
    }
};

/// Lowers the running distances of points [begin, end) to the newest centre and returns the
/// farthest of them: the first index holding the largest distance, as a sequential scan that
/// keeps only strictly larger ones would (a NaN distance never wins). Same arithmetic per
/// point as the scalar form, so the same indices.
Farthest update_chunk(const AxisArrays& points, float* min_sq_distance, const float* centre,
                      int64_t begin, int64_t end) {
    const float *x = points.x.data(), *y = points.y.data(), *z = points.z.data();
    const float cx = centre[0], cy = centre[1], cz = centre[2];
    const Float4 cx4 = {cx, cx, cx, cx}, cy4 = {cy, cy, cy, cy}, cz4 = {cz, cz, cz, cz};
    const float none = Farthest{}.sq_distance;
    Float4 lane_max[kFpsVectors];
    for (Float4& lanes : lane_max) lanes = Float4{none, none, none, none};
    int64_t j = begin;
    for (; j + kFpsLanes <= end; j += kFpsLanes)
        for (int v = 0; v < kFpsVectors; ++v) {
            const int64_t i = j + 4 * v;
            const Float4 dx = load4(x + i) - cx4, dy = load4(y + i) - cy4, dz = load4(z + i) - cz4;
            const Float4 d = dx * dx + dy * dy + dz * dz;
            const Float4 old = load4(min_sq_distance + i);
            const Float4 lowered = d < old ? d : old;
            std::memcpy(min_sq_distance + i, &lowered, sizeof lowered);
            lane_max[v] = lowered > lane_max[v] ? lowered : lane_max[v];
        }
    float largest = none;
    for (; j < end; ++j) {
        const float dx = x[j] - cx, dy = y[j] - cy, dz = z[j] - cz;
        const float d = dx * dx + dy * dy + dz * dz;
        if (d < min_sq_distance[j]) min_sq_distance[j] = d;
        if (min_sq_distance[j] > largest) largest = min_sq_distance[j];
    }
    for (const Float4& lanes : lane_max)
        for (int k = 0; k < 4; ++k)
            if (lanes[k] > largest) largest = lanes[k];
    if (!(largest > none)) return {};
    for (j = begin; j < end; ++j)
        if (min_sq_distance[j] == largest) return {largest, j};
    return {};
}

/// FPS over float32 [n,3] CPU coordinates: writes m >= 1 indices to `out`, starting at
/// `start`. Parallel over chunks of points when there are several.
void farthest_point_sampling_cpu(const float* xyz, int64_t n, int64_t m, int64_t start,
                                 int64_t* out) {
    const AxisArrays points(xyz, n);
    std::vector<float> min_sq_distance(n, std::numeric_limits<float>::infinity());
    const int64_t num_chunks = (n + kFpsChunk - 1) / kFpsChunk;
    std::vector<Farthest> chunk_best(num_chunks);
    int64_t current = start;
    for (int64_t i = 0; i < m; ++i) {
        out[i] = current;
        if (i + 1 == m) break;
        const float* centre = xyz + 3 * current;
        auto update = [&](int64_t chunk) {
            chunk_best[chunk] =
                update_chunk(points, min_sq_distance.data(), centre, chunk * kFpsChunk,
                             std::min(n, (chunk + 1) * kFpsChunk));
        };
        if (num_chunks == 1) {
            update(0);
        } else {
            at::parallel_for(0, num_chunks, 1, [&](int64_t begin, int64_t end) {
                for (int64_t chunk = begin; chunk < end; ++chunk) update(chunk);
            });
        }
        Farthest best;
        for (const Farthest& candidate : chunk_best)
            if (candidate.sq_distance > best.sq_distance) best = candidate;
        if (best.index < 0)
            throw_input_error("farthest_point_sampling", "points have non-finite coordinates");
        current = best.index;
    }
}

/// The k-d tree of the pruned FPS: each node holds a range of the points in tree order, their
/// bounding box and the farthest of them (original index).
struct FpsNode {
    float lo[3], hi[3];
    Farthest best{std::numeric_limits<float>::infinity(), -1};
    int64_t begin = 0, end = 0;
    int32_t left = -1, right = -1;
};

/// Points per leaf of the pruned FPS's tree (bench_geometry_sampling).
constexpr int64_t kFpsLeaf = 64;

/// The better of two candidates: the larger distance, ties to the smaller original index.
Farthest farther(const Farthest& a, const Farthest& b) {
    if (a.sq_distance != b.sq_distance) return a.sq_distance > b.sq_distance ? a : b;
    return a.index <= b.index ? a : b;
}

/// FPS with the same answer as farthest_point_sampling_cpu(), pruned by a k-d tree: a node
/// whose box is no nearer to the new centre than its farthest point's running distance keeps
/// every running distance of its points, so it is skipped. The work per pick falls from N to
/// the points near the pick once picks are dense. Finite coordinates only; one thread.
class PrunedFps {
  public:
    PrunedFps(const float* xyz, int64_t n) : xyz_(xyz), order_(n), min_sq_distance_(n) {
        std::iota(order_.begin(), order_.end(), int64_t{0});
        nodes_.reserve(static_cast<size_t>(4 * (n / kFpsLeaf + 1)));
        build(0, n);
        // Leaves in original index order, so that update_chunk's first-largest is the smallest
        // original index within a leaf.
        for (const FpsNode& node : nodes_)
            if (node.left < 0) std::sort(order_.begin() + node.begin, order_.begin() + node.end);
        std::vector<float> in_order(3 * n);
        for (int64_t k = 0; k < n; ++k)
            std::memcpy(&in_order[3 * k], xyz + 3 * order_[k], 3 * sizeof(float));
        points_.emplace(in_order.data(), n);
        std::fill(min_sq_distance_.begin(), min_sq_distance_.end(),
                  std::numeric_limits<float>::infinity());
    }

    void run(int64_t m, int64_t start, int64_t* out) {
        int64_t current = start;
        for (int64_t i = 0; i < m; ++i) {
            out[i] = current;
            if (i + 1 == m) break;
            update(0, xyz_ + 3 * current);
            current = nodes_[0].best.index;
        }
    }

  private:
    int32_t build(int64_t begin, int64_t end) {
        const auto id = static_cast<int32_t>(nodes_.size());
        nodes_.emplace_back();
        FpsNode node;
        node.begin = begin;
        node.end = end;
        for (int axis = 0; axis < 3; ++axis) {
            node.lo[axis] = std::numeric_limits<float>::infinity();
            node.hi[axis] = -std::numeric_limits<float>::infinity();
        }
        for (int64_t k = begin; k < end; ++k)
            for (int axis = 0; axis < 3; ++axis) {
                const float v = xyz_[3 * order_[k] + axis];
                node.lo[axis] = std::min(node.lo[axis], v);
                node.hi[axis] = std::max(node.hi[axis], v);
            }
        if (end - begin > kFpsLeaf) {
            int widest = 0;
            for (int axis = 1; axis < 3; ++axis)
                if (node.hi[axis] - node.lo[axis] > node.hi[widest] - node.lo[widest])
                    widest = axis;
            const int64_t middle = begin + (end - begin) / 2;
            std::nth_element(
                order_.begin() + begin, order_.begin() + middle, order_.begin() + end,
                [&](int64_t a, int64_t b) { return xyz_[3 * a + widest] < xyz_[3 * b + widest]; });
            node.left = build(begin, middle);
            node.right = build(middle, end);
        }
        nodes_[id] = node;
        return id;
    }

    /// A lower bound of the squared distance from `centre` to any point in the node's box, in
    /// the distance update's arithmetic, shrunk by a relative 1e-6 so that no rounding (nor a
    /// fused multiply-add in one form and not the other) can lift it above a point's own.
    static float box_sq_distance(const FpsNode& node, const float* centre) {
        float gap[3];
        for (int axis = 0; axis < 3; ++axis) {
            const float c = centre[axis];
            gap[axis] = c < node.lo[axis] ? node.lo[axis] - c
                                          : (c > node.hi[axis] ? c - node.hi[axis] : 0.f);
        }
        return (gap[0] * gap[0] + gap[1] * gap[1] + gap[2] * gap[2]) * (1.f - 1e-6f);
    }

    void update(int32_t id, const float* centre) {
        FpsNode& node = nodes_[id];
        if (box_sq_distance(node, centre) >= node.best.sq_distance) return;
        if (node.left < 0) {
            const Farthest f =
                update_chunk(*points_, min_sq_distance_.data(), centre, node.begin, node.end);
            node.best = {f.sq_distance, order_[f.index]};
            return;
        }
        update(node.left, centre);
        update(node.right, centre);
        node.best = farther(nodes_[node.left].best, nodes_[node.right].best);
    }

    const float* xyz_;
    std::vector<int64_t> order_;  ///< tree position -> original index
    std::vector<float> min_sq_distance_;
    std::optional<AxisArrays> points_;  ///< coordinates in tree order
    std::vector<FpsNode> nodes_;
};

/// FPS's argument checks and its CPU copy of the points; calls `pick(xyz, n, indices)` for
/// m >= 1 and returns the indices on the points' device.
template <typename Pick>
at::Tensor fps_on_cpu(const at::Tensor& points, int64_t m, int64_t start, Pick&& pick) {
    check_points(points, "farthest_point_sampling");
    const int64_t n = points.size(0);
    if (m < 0 || m > n)
        throw_input_error("farthest_point_sampling", "cannot pick {} of {} points", m, n);
    at::Tensor indices = at::empty({m}, at::kLong);
    if (m == 0) return indices.to(points.device());
    if (start < 0 || start >= n)
        throw_input_error("farthest_point_sampling", "start index {} out of range [0, {})", start,
                          n);
    at::Tensor cpu = points.to(at::kCPU).contiguous();
    pick(cpu, n, indices.data_ptr<int64_t>());
    return indices.to(points.device());
}

/// A point's coordinates as bits, with -0 read as 0, for exact equality and hashing.
struct PointKey {
    uint32_t x, y, z;
    bool operator==(const PointKey& other) const {
        return x == other.x && y == other.y && z == other.z;
    }
};

struct PointKeyHash {
    size_t operator()(const PointKey& key) const {
        uint64_t h = key.x * 0x9E3779B97F4A7C15ull;
        h ^= (h >> 29) + key.y * 0xBF58476D1CE4E5B9ull;
        h ^= (h >> 31) + key.z * 0x94D049BB133111EBull;
        return static_cast<size_t>(h ^ (h >> 32));
    }
};

uint32_t coordinate_bits(float value) {
    if (value == 0.0f) value = 0.0f;
    uint32_t bits;
    std::memcpy(&bits, &value, sizeof bits);
    return bits;
}

/// The keys of float32 [N,3] points, in order.
std::vector<PointKey> point_keys(const at::Tensor& points) {
    at::Tensor cpu = points.to(at::kCPU).contiguous();
    const float* p = cpu.data_ptr<float>();
    std::vector<PointKey> keys(static_cast<size_t>(cpu.size(0)));
    for (size_t i = 0; i < keys.size(); ++i)
        keys[i] = {coordinate_bits(p[3 * i]), coordinate_bits(p[3 * i + 1]),
                   coordinate_bits(p[3 * i + 2])};
    return keys;
}

}  // namespace

at::Tensor farthest_point_sampling_pruned(const at::Tensor& points, int64_t m, int64_t start) {
    return fps_on_cpu(points, m, start, [&](const at::Tensor& cpu, int64_t n, int64_t* out) {
        if (!at::isfinite(cpu).all().item<bool>())
            throw_input_error("farthest_point_sampling", "points have non-finite coordinates");
        PrunedFps(cpu.data_ptr<float>(), n).run(m, start, out);
    });
}

at::Tensor farthest_point_sampling(const at::Tensor& points, int64_t m, int64_t start) {
    return fps_on_cpu(points, m, start, [&](const at::Tensor& cpu, int64_t n, int64_t* out) {
        farthest_point_sampling_cpu(cpu.data_ptr<float>(), n, m, start, out);
    });
}

at::Tensor farthest_point_sampling_batched(const at::Tensor& points, int64_t m) {
    check_batched_points(points, "farthest_point_sampling_batched");
    const int64_t batch = points.size(0), n = points.size(1);
    if (m < 0 || m > n)
        throw_input_error("farthest_point_sampling_batched", "cannot pick {} of {} points", m, n);
    const auto long_options = points.options().dtype(at::kLong);
    at::Tensor indices = at::empty({batch, m}, long_options);
    if (m == 0) return indices;
    if (points.device().is_cpu() && points.scalar_type() == at::kFloat) {
        // The raw loop, one element per task: 3x faster than the tensor ops below (measured),
        // with the same answer.
        at::Tensor cpu = points.contiguous();
        const float* xyz = cpu.data_ptr<float>();
        int64_t* out = indices.data_ptr<int64_t>();
        at::parallel_for(0, batch, 1, [&](int64_t begin, int64_t end) {
            for (int64_t b = begin; b < end; ++b)
                farthest_point_sampling_cpu(xyz + 3 * n * b, n, m, 0, out + m * b);
        });
        return indices;
    }

    at::NoGradGuard no_grad;
    at::Tensor current = at::zeros({batch}, long_options);
    at::Tensor min_sq_distance = at::full({batch, n}, INFINITY, points.options());
    for (int64_t i = 0; i < m; ++i) {
        indices.select(1, i).copy_(current);
        if (i + 1 == m) break;
        at::Tensor centre = points.gather(1, current.view({batch, 1, 1}).expand({batch, 1, 3}));
        // Per-axis terms summed in x, y, z order: the same float operations as the CPU loop.
        at::Tensor sq_distance;
        for (int64_t axis = 0; axis < 3; ++axis) {
            at::Tensor diff = points.select(2, axis) - centre.select(2, axis);
            at::Tensor term = diff.mul_(diff);
            sq_distance = axis == 0 ? term : sq_distance.add_(term);
        }
        at::minimum_out(min_sq_distance, min_sq_distance, sq_distance);
        current = min_sq_distance.argmax(1);
    }
    return indices;
}

at::Tensor distinct_points(const at::Tensor& points, const at::Tensor& exclude) {
    check_points(points, "distinct_points");
    std::unordered_set<PointKey, PointKeyHash> seen;
    if (exclude.defined()) {
        check_points(exclude, "distinct_points exclude");
        for (const PointKey& key : point_keys(exclude)) seen.insert(key);
    }
    const std::vector<PointKey> keys = point_keys(points);
    seen.reserve(seen.size() + keys.size());
    std::vector<int64_t> kept;
    kept.reserve(keys.size());
    for (size_t i = 0; i < keys.size(); ++i)
        if (seen.insert(keys[i]).second) kept.push_back(static_cast<int64_t>(i));
    return at::tensor(kept, at::TensorOptions(at::kLong)).to(points.device());
}

int64_t count_distinct_points(const at::Tensor& points) { return distinct_points(points).size(0); }

at::Tensor uniform_random_points(int64_t n, uint64_t seed) {
    if (n < 0) throw_input_error("uniform_random_points", "cannot draw {} points", n);
    std::mt19937_64 rng(seed);
    std::uniform_real_distribution<float> uniform(-1.f, 1.f);
    at::Tensor points = at::empty({n, 3}, at::kFloat);
    float* p = points.data_ptr<float>();
    for (int64_t i = 0; i < 3 * n; ++i) p[i] = uniform(rng);
    return points;
}

at::Tensor random_subset(int64_t n, int64_t m, uint64_t seed) {
    if (m < 0 || m > n)
        throw_input_error("random_subset", "cannot draw {} distinct indices from {}", m, n);
    // Floyd's algorithm: m draws, each index equally likely to end up in the subset.
    std::mt19937_64 rng(seed);
    std::vector<bool> taken(n, false);
    std::vector<int64_t> chosen;
    chosen.reserve(m);
    for (int64_t j = n - m; j < n; ++j) {
        int64_t candidate = std::uniform_int_distribution<int64_t>(0, j)(rng);
        if (taken[candidate]) candidate = j;
        taken[candidate] = true;
        chosen.push_back(candidate);
    }
    std::sort(chosen.begin(), chosen.end());
    return at::tensor(chosen, at::kLong);
}

at::Tensor nonuniform_subset(int64_t n, int64_t m, uint64_t seed) {
    if (m < 0 || m > n)
        throw_input_error("nonuniform_subset", "cannot draw {} distinct indices from {}", m, n);
    std::mt19937_64 rng(seed);
    const double loc = std::uniform_real_distribution<double>(0.1, 0.9)(rng);
    std::normal_distribution<double> normal(loc, 0.3);
    std::vector<bool> taken(n, false);
    std::vector<int64_t> chosen;
    chosen.reserve(m);
    // Terminates even for m == n: every index has probability above 0.014/n per draw (loc is
    // at most 3 sigma from either end), so the expected number of draws is O(n log n).
    while (static_cast<int64_t>(chosen.size()) < m) {
        const double scaled = normal(rng) * static_cast<double>(n);
        // Python's int() truncates towards zero: (-1, 0) maps to index 0, as in PU-GAN.
        if (!(scaled > -1.0 && scaled < static_cast<double>(n))) continue;
        const auto index = static_cast<int64_t>(scaled);
        if (taken[index]) continue;
        taken[index] = true;
        chosen.push_back(index);
    }
    return at::tensor(chosen, at::kLong);
}

PointCloud sample_uniform(const TriangleMesh& mesh, int64_t n, uint64_t seed) {
    check_points(mesh.vertices, "sample_uniform: vertices");
    check_faces(mesh.faces, mesh.num_vertices(), "sample_uniform: faces");
    if (n < 0) throw_input_error("sample_uniform", "negative sample count {}", n);
    at::Tensor vertices = mesh.vertices.to(at::kCPU).contiguous();
    at::Tensor faces = mesh.faces.to(at::kCPU).contiguous();
    const float* v = vertices.data_ptr<float>();
    const int64_t* f = faces.data_ptr<int64_t>();
    const int64_t num_faces = faces.size(0);

    // Cumulative doubled areas (the factor cancels) and unit face normals.
    std::vector<double> cumulative(num_faces);
    std::vector<float> normals(3 * num_faces);
    double total = 0.0;
    int64_t last_positive = -1;
    for (int64_t t = 0; t < num_faces; ++t) {
        const float* a = v + 3 * f[3 * t];
        const float* b = v + 3 * f[3 * t + 1];
        const float* c = v + 3 * f[3 * t + 2];
        const double e1[3] = {double(b[0]) - a[0], double(b[1]) - a[1], double(b[2]) - a[2]};
        const double e2[3] = {double(c[0]) - a[0], double(c[1]) - a[1], double(c[2]) - a[2]};
        const double cross[3] = {e1[1] * e2[2] - e1[2] * e2[1], e1[2] * e2[0] - e1[0] * e2[2],
                                 e1[0] * e2[1] - e1[1] * e2[0]};
        const double doubled_area =
            std::sqrt(cross[0] * cross[0] + cross[1] * cross[1] + cross[2] * cross[2]);
        for (int axis = 0; axis < 3; ++axis)
            normals[3 * t + axis] =
                doubled_area > 0 ? static_cast<float>(cross[axis] / doubled_area) : 0.f;
        total += doubled_area;
        cumulative[t] = total;
        if (doubled_area > 0) last_positive = t;
    }
    if (!(total > 0) || !std::isfinite(total))
        throw_input_error("sample_uniform", "mesh has no face with positive finite area");
    // Guide table (Chen & Asau 1974): guide[b] is the face holding the draw b / F of the total,
    // so the face search starts next to its answer (O(1) expected instead of a binary search;
    // 2x faster sampling on a 50k-face mesh, measured).
    std::vector<int64_t> guide(num_faces);
    for (int64_t b = 0, t = 0; b < num_faces; ++b) {
        const double x = total * static_cast<double>(b) / static_cast<double>(num_faces);
        while (t < last_positive && cumulative[t] <= x) ++t;
        guide[b] = t;
    }

    PointCloud cloud{at::empty({n, 3}, at::kFloat), at::empty({n, 3}, at::kFloat), {}};
    float* points_out = cloud.points.data_ptr<float>();
    float* normals_out = cloud.normals.data_ptr<float>();
    std::mt19937_64 rng(seed);
    std::uniform_real_distribution<double> uniform(0.0, 1.0);
    for (int64_t i = 0; i < n; ++i) {
        // The first face whose cumulative area exceeds the draw (the last positive one if
        // rounding lands on the total): zero-area faces add no interval and are never chosen.
        const double u = uniform(rng), x = u * total;
        int64_t t = guide[std::min<int64_t>(static_cast<int64_t>(u * num_faces), num_faces - 1)];
        while (t < last_positive && cumulative[t] <= x) ++t;
        while (t > 0 && cumulative[t - 1] > x) --t;
        // sqrt of the first draw makes the barycentric density uniform over the triangle.
        const double s = std::sqrt(uniform(rng));
        const double r = uniform(rng);
        const double weights[3] = {1.0 - s, s * (1.0 - r), s * r};
        for (int axis = 0; axis < 3; ++axis) {
            double coordinate = 0.0;
            for (int corner = 0; corner < 3; ++corner)
                coordinate += weights[corner] * v[3 * f[3 * t + corner] + axis];
            points_out[3 * i + axis] = static_cast<float>(coordinate);
            normals_out[3 * i + axis] = normals[3 * t + axis];
        }
    }
    return cloud;
}

at::Tensor random_rotation(std::mt19937_64& rng) {
    // A uniformly random rotation from a random unit quaternion (Shoemake).
    std::uniform_real_distribution<double> u(0.0, 1.0);
    double u1 = u(rng), u2 = u(rng), u3 = u(rng);
    double a = std::sqrt(1 - u1), b = std::sqrt(u1);
    double x = a * std::sin(2 * M_PI * u2), y = a * std::cos(2 * M_PI * u2);
    double z = b * std::sin(2 * M_PI * u3), w = b * std::cos(2 * M_PI * u3);
    return at::tensor({1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w),
                       2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w),
                       2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)},
                      at::kFloat)
        .view({3, 3});
}

}  // namespace pumeta
