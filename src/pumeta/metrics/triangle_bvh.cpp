// The triangle BVH (median splits, ordered closest-point traversal), the exact
// point-triangle distance it evaluates at its leaves, and first-hit ray casting through it.
#include "pumeta/metrics/triangle_bvh.h"

#include <ATen/ATen.h>
#include <ATen/Parallel.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <numeric>
#include <vector>

#include "pumeta/core/error.h"
#include "pumeta/core/tensor_checks.h"

namespace pumeta {

namespace {

using Vec3 = std::array<double, 3>;

Vec3 sub(const double a[3], const double b[3]) { return {a[0] - b[0], a[1] - b[1], a[2] - b[2]}; }

double dot(const Vec3& a, const Vec3& b) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }

Vec3 cross(const Vec3& a, const Vec3& b) {
    return {a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]};
}

/// Squared distance from p to the closest point of a + t (b - a), t in [0,1]; a point when
/// a == b.
double point_segment_sq_distance(const double p[3], const double a[3], const double b[3]) {
    Vec3 ab = sub(b, a);
    Vec3 ap = sub(p, a);
    double length_sq = dot(ab, ab);
    double t = length_sq > 0 ? std::clamp(dot(ap, ab) / length_sq, 0.0, 1.0) : 0.0;
    Vec3 d = {ap[0] - t * ab[0], ap[1] - t * ab[1], ap[2] - t * ab[2]};
    return dot(d, d);
}

/// Squared distance from p to the triangle, found through p's Voronoi region (Ericson
/// 5.1.5). `normal` = (b - a) x (c - a). The caller guarantees a non-degenerate triangle, so
/// the edge divisors are positive squared edge lengths. In the face region the distance to
/// the plane is used instead of Ericson's barycentric closest point: it stays accurate on
/// slivers, where va + vb + vc (the squared area) suffers cancellation.
double ericson_sq_distance(const double p[3], const double a[3], const double b[3],
                           const double c[3], const Vec3& normal) {
    Vec3 ab = sub(b, a), ac = sub(c, a), ap = sub(p, a);
    double d1 = dot(ab, ap), d2 = dot(ac, ap);
    if (d1 <= 0 && d2 <= 0) return dot(ap, ap);  // vertex a

    Vec3 bp = sub(p, b);
    double d3 = dot(ab, bp), d4 = dot(ac, bp);
    if (d3 >= 0 && d4 <= d3) return dot(bp, bp);  // vertex b

    // |p - (a + v ab + w ac)|^2
    auto sq_distance_to = [&](double v, double w) {
        Vec3 d = {ap[0] - v * ab[0] - w * ac[0], ap[1] - v * ab[1] - w * ac[1],
                  ap[2] - v * ab[2] - w * ac[2]};
        return dot(d, d);
    };
    double vc = d1 * d4 - d3 * d2;
    if (vc <= 0 && d1 >= 0 && d3 <= 0) return sq_distance_to(d1 / (d1 - d3), 0);  // edge ab

    Vec3 cp = sub(p, c);
    double d5 = dot(ab, cp), d6 = dot(ac, cp);
    if (d6 >= 0 && d5 <= d6) return dot(cp, cp);  // vertex c

    double vb = d5 * d2 - d1 * d6;
    if (vb <= 0 && d2 >= 0 && d6 <= 0) return sq_distance_to(0, d2 / (d2 - d6));  // edge ac

    double va = d3 * d6 - d5 * d4;
    if (va <= 0 && (d4 - d3) >= 0 && (d5 - d6) >= 0) {  // edge bc
        double w = (d4 - d3) / ((d4 - d3) + (d5 - d6));
        return sq_distance_to(1 - w, w);
    }
    double height = dot(ap, normal);  // face interior
    return height * height / dot(normal, normal);
}

/// Triangles whose doubled area |ab x ac| is at most this fraction of their longest edge
/// squared are treated as their three edges. Their height is then below this fraction of
/// the longest edge, which bounds the error of doing so; above it, rounding in Ericson's
/// region tests misplaces region borders by about the same amount.
constexpr double kDegenerateRatio = 1e-8;

double point_triangle_sq_distance(const double p[3], const double a[3], const double b[3],
                                  const double c[3]) {
    Vec3 ab = sub(b, a), ac = sub(c, a), bc = sub(c, b);
    Vec3 normal = cross(ab, ac);
    double longest_sq = std::max({dot(ab, ab), dot(ac, ac), dot(bc, bc)});
    if (std::sqrt(dot(normal, normal)) > kDegenerateRatio * longest_sq)
        return ericson_sq_distance(p, a, b, c, normal);
    return std::min({point_segment_sq_distance(p, a, b), point_segment_sq_distance(p, a, c),
                     point_segment_sq_distance(p, b, c)});
}

struct Aabb {
    Vec3 lo{std::numeric_limits<double>::infinity(), std::numeric_limits<double>::infinity(),
            std::numeric_limits<double>::infinity()};
    Vec3 hi{-std::numeric_limits<double>::infinity(), -std::numeric_limits<double>::infinity(),
            -std::numeric_limits<double>::infinity()};

    void grow(const double p[3]) {
        for (int d = 0; d < 3; ++d) {
            lo[d] = std::min(lo[d], p[d]);
            hi[d] = std::max(hi[d], p[d]);
        }
    }
    void grow(const Aabb& box) {
        grow(box.lo.data());
        grow(box.hi.data());
    }
    /// Squared distance from p to the box (0 inside): a lower bound for every triangle in it.
    double sq_distance(const double p[3]) const {
        double sum = 0;
        for (int d = 0; d < 3; ++d) {
            double excess = std::max({lo[d] - p[d], 0.0, p[d] - hi[d]});
            sum += excess * excess;
        }
        return sum;
    }
    /// The ray parameter where origin + t·direction enters the box (slab test; inv = 1 /
    /// direction per axis, infinite for a zero component), or +infinity when it misses the box
    /// within (0, max_t].
    double entry(const double origin[3], const double inv[3], double max_t) const {
        double near = 0, far = max_t;
        for (int d = 0; d < 3; ++d) {
            double t0 = (lo[d] - origin[d]) * inv[d], t1 = (hi[d] - origin[d]) * inv[d];
            if (t0 > t1) std::swap(t0, t1);
            // NaN (0 · infinity: the ray lies in a slab plane) compares false: no narrowing.
            if (t0 > near) near = t0;
            if (t1 < far) far = t1;
            if (near > far) return std::numeric_limits<double>::infinity();
        }
        return near;
    }
};

/// Barycentric slack of ray_triangle: a ray through an edge shared by two triangles would
/// otherwise miss both when rounding puts it just outside each; it widens each triangle by
/// this fraction of its size.
constexpr double kEdgeSlack = 1e-9;

/// Möller–Trumbore: the t > 0 where the ray crosses triangle (a, b, c), +infinity when it
/// does not (or the triangle is degenerate, or the ray is parallel to its plane).
double ray_triangle(const double origin[3], const double direction[3], const double a[3],
                    const double b[3], const double c[3]) {
    constexpr double kInf = std::numeric_limits<double>::infinity();
    Vec3 ab = sub(b, a), ac = sub(c, a);
    Vec3 dir = {direction[0], direction[1], direction[2]};
    Vec3 p = cross(dir, ac);
    double det = dot(ab, p);
    if (det == 0 || !std::isfinite(det)) return kInf;
    double inv_det = 1.0 / det;
    Vec3 ao = sub(origin, a);
    double u = dot(ao, p) * inv_det;
    if (u < -kEdgeSlack || u > 1 + kEdgeSlack) return kInf;
    Vec3 q = cross(ao, ab);
    double v = dot(dir, q) * inv_det;
    if (v < -kEdgeSlack || u + v > 1 + kEdgeSlack) return kInf;
    double t = dot(ac, q) * inv_det;
    return t > 0 ? t : kInf;
}

/// Leaves hold at most this many triangles: below it, testing them all beats descending.
constexpr int64_t kLeafSize = 4;

struct Node {
    Aabb box;
    // Inner node: children nodes[first] and nodes[first + 1], count == 0.
    // Leaf: triangles[first, first + count), the triangles being stored in leaf order.
    int64_t first = 0;
    int64_t count = 0;
};

}  // namespace

double point_triangle_distance(const double p[3], const double a[3], const double b[3],
                               const double c[3]) {
    return std::sqrt(point_triangle_sq_distance(p, a, b, c));
}

struct TriangleBvh::Impl {
    std::vector<std::array<Vec3, 3>> triangles;  // in leaf order after the build
    std::vector<Node> nodes;                     // nodes[0] is the root

    explicit Impl(std::vector<std::array<Vec3, 3>> input);
    double sq_distance(const double p[3]) const;
    double first_hit(const double origin[3], const double direction[3], double max_t) const;
};

TriangleBvh::Impl::Impl(std::vector<std::array<Vec3, 3>> input) {
    const int64_t n = static_cast<int64_t>(input.size());
    std::vector<Vec3> centroids(n);
    std::vector<Aabb> boxes(n);
    for (int64_t i = 0; i < n; ++i) {
        for (const Vec3& v : input[i]) boxes[i].grow(v.data());
        for (int d = 0; d < 3; ++d)
            centroids[i][d] = (input[i][0][d] + input[i][1][d] + input[i][2][d]) / 3;
    }
    std::vector<int64_t> order(n);
    std::iota(order.begin(), order.end(), 0);

    // Top-down: split each node at the median centroid along the longest axis of its
    // centroids' extent. Median splits give a balanced tree of depth log2(n / kLeafSize)
    // whatever the triangle distribution; ranges are processed with an explicit stack.
    nodes.reserve(2 * (n / kLeafSize + 1));
    nodes.push_back({Aabb{}, 0, n});
    std::vector<int64_t> pending = {0};
    while (!pending.empty()) {
        int64_t index = pending.back();
        pending.pop_back();
        const int64_t first = nodes[index].first, count = nodes[index].count;
        Aabb box, centroid_box;
        for (int64_t i = first; i < first + count; ++i) {
            box.grow(boxes[order[i]]);
            centroid_box.grow(centroids[order[i]].data());
        }
        nodes[index].box = box;
        if (count <= kLeafSize) continue;

        int axis = 0;
        for (int d = 1; d < 3; ++d) {
            if (centroid_box.hi[d] - centroid_box.lo[d] >
                centroid_box.hi[axis] - centroid_box.lo[axis])
                axis = d;
        }
        const int64_t half = count / 2;
        std::nth_element(
            order.begin() + first, order.begin() + first + half, order.begin() + first + count,
            [&](int64_t i, int64_t j) { return centroids[i][axis] < centroids[j][axis]; });
        const int64_t left = static_cast<int64_t>(nodes.size());
        nodes[index].first = left;
        nodes[index].count = 0;
        nodes.push_back({Aabb{}, first, half});
        nodes.push_back({Aabb{}, first + half, count - half});
        pending.push_back(left);
        pending.push_back(left + 1);
    }
    triangles.resize(n);
    for (int64_t i = 0; i < n; ++i) triangles[i] = input[order[i]];
}

double TriangleBvh::Impl::sq_distance(const double p[3]) const {
    double best = std::numeric_limits<double>::infinity();
    // Depth-first, nearer child first, each entry carrying its box distance so that a node
    // is skipped once a closer triangle has been found after it was pushed. The stack holds
    // at most one pending sibling per level plus one: median splits keep the depth below
    // 64 for any int64 triangle count, so a fixed array suffices.
    struct Entry {
        int64_t node;
        double box_sq_distance;
    };
    std::array<Entry, 65> stack;
    int size = 0;
    stack[size++] = {0, nodes[0].box.sq_distance(p)};
    while (size > 0) {
        Entry entry = stack[--size];
        if (entry.box_sq_distance >= best) continue;
        const Node& node = nodes[entry.node];
        if (node.count > 0) {
            for (int64_t i = node.first; i < node.first + node.count; ++i) {
                const auto& t = triangles[i];
                best = std::min(
                    best, point_triangle_sq_distance(p, t[0].data(), t[1].data(), t[2].data()));
            }
            continue;
        }
        double near_sq = nodes[node.first].box.sq_distance(p);
        double far_sq = nodes[node.first + 1].box.sq_distance(p);
        int64_t near = node.first, far = node.first + 1;
        if (far_sq < near_sq) {
            std::swap(near, far);
            std::swap(near_sq, far_sq);
        }
        if (far_sq < best) stack[size++] = {far, far_sq};
        if (near_sq < best) stack[size++] = {near, near_sq};
    }
    return best;
}

double TriangleBvh::Impl::first_hit(const double origin[3], const double direction[3],
                                    double max_t) const {
    double inv[3];
    for (int d = 0; d < 3; ++d) inv[d] = 1.0 / direction[d];  // ±infinity for 0
    double best = max_t;
    bool found = false;
    // Depth-first, nearer box first; an entry is skipped once a hit closer than its box's
    // entry point has been found. The depth bound of sq_distance applies.
    struct Entry {
        int64_t node;
        double t;
    };
    std::array<Entry, 65> stack;
    int size = 0;
    double root_t = nodes[0].box.entry(origin, inv, best);
    if (!std::isfinite(root_t)) return std::numeric_limits<double>::infinity();
    stack[size++] = {0, root_t};
    while (size > 0) {
        Entry entry = stack[--size];
        if (entry.t > best) continue;
        const Node& node = nodes[entry.node];
        if (node.count > 0) {
            for (int64_t i = node.first; i < node.first + node.count; ++i) {
                const auto& t = triangles[i];
                double hit = ray_triangle(origin, direction, t[0].data(), t[1].data(), t[2].data());
                if (hit <= best) {
                    best = hit;
                    found = true;
                }
            }
            continue;
        }
        int64_t near = node.first, far = node.first + 1;
        double near_t = nodes[near].box.entry(origin, inv, best);
        double far_t = nodes[far].box.entry(origin, inv, best);
        if (far_t < near_t) {
            std::swap(near, far);
            std::swap(near_t, far_t);
        }
        // entry() is +infinity for a missed box, also when max_t is.
        if (std::isfinite(far_t) && far_t <= best) stack[size++] = {far, far_t};
        if (std::isfinite(near_t) && near_t <= best) stack[size++] = {near, near_t};
    }
    return found ? best : std::numeric_limits<double>::infinity();
}

TriangleBvh::TriangleBvh(const TriangleMesh& mesh) {
    check_points(mesh.vertices, "mesh vertices", 1);
    check_faces(mesh.faces, mesh.num_vertices(), "mesh faces");
    if (mesh.num_faces() == 0) throw_input_error("mesh faces", "the mesh has no triangles");
    at::Tensor vertices = mesh.vertices.to(at::kCPU, at::kDouble).contiguous();
    at::Tensor faces = mesh.faces.to(at::kCPU).contiguous();
    const double* v = vertices.data_ptr<double>();
    const int64_t* f = faces.data_ptr<int64_t>();
    std::vector<std::array<Vec3, 3>> triangles(mesh.num_faces());
    for (size_t i = 0; i < triangles.size(); ++i) {
        for (int corner = 0; corner < 3; ++corner) {
            const double* vertex = v + 3 * f[3 * i + corner];
            triangles[i][corner] = {vertex[0], vertex[1], vertex[2]};
        }
    }
    impl_ = std::make_unique<Impl>(std::move(triangles));
}

TriangleBvh::~TriangleBvh() = default;
TriangleBvh::TriangleBvh(TriangleBvh&&) noexcept = default;
TriangleBvh& TriangleBvh::operator=(TriangleBvh&&) noexcept = default;

at::Tensor TriangleBvh::distances(const at::Tensor& queries) const {
    check_points(queries, "queries");
    at::Tensor points = queries.to(at::kCPU, at::kDouble).contiguous();
    const int64_t count = points.size(0);
    at::Tensor result = at::empty({count}, at::kDouble);
    const double* p = points.data_ptr<double>();
    double* out = result.data_ptr<double>();
    // A query costs a few microseconds: chunks of 256 amortise the scheduling.
    at::parallel_for(0, count, 256, [&](int64_t begin, int64_t end) {
        for (int64_t i = begin; i < end; ++i) out[i] = std::sqrt(impl_->sq_distance(p + 3 * i));
    });
    return result;
}

double TriangleBvh::first_hit(const double origin[3], const double direction[3],
                              double max_t) const {
    return impl_->first_hit(origin, direction, max_t);
}

at::Tensor TriangleBvh::first_hits(const at::Tensor& origins, const at::Tensor& directions,
                                   double max_t) const {
    for (const auto& [tensor, what] :
         {std::pair{&origins, "ray origins"}, std::pair{&directions, "ray directions"}}) {
        if (!tensor->defined() || tensor->dim() != 2 || tensor->size(1) != 3 ||
            (tensor->scalar_type() != at::kFloat && tensor->scalar_type() != at::kDouble))
            throw_input_error(what, "expected float32 or float64 [Q,3], found {}",
                              shape_string(*tensor));
    }
    if (origins.size(0) != directions.size(0))
        throw_input_error("rays", "{} origins but {} directions", origins.size(0),
                          directions.size(0));
    at::Tensor o = origins.to(at::kCPU, at::kDouble).contiguous();
    at::Tensor d = directions.to(at::kCPU, at::kDouble).contiguous();
    const int64_t count = o.size(0);
    at::Tensor result = at::empty({count}, at::kDouble);
    const double* op = o.data_ptr<double>();
    const double* dp = d.data_ptr<double>();
    double* out = result.data_ptr<double>();
    at::parallel_for(0, count, 256, [&](int64_t begin, int64_t end) {
        for (int64_t i = begin; i < end; ++i)
            out[i] = impl_->first_hit(op + 3 * i, dp + 3 * i, max_t);
    });
    return result;
}

}  // namespace pumeta
