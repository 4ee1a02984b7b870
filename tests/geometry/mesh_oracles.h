// Small meshes and a brute-force point-to-mesh distance for the sampling tests.
#pragma once

#include <ATen/ATen.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <vector>

#include "pumeta/geometry/point_cloud.h"

namespace pumeta::test {

using Vec3 = std::array<double, 3>;

inline Vec3 sub(const Vec3& a, const Vec3& b) { return {a[0] - b[0], a[1] - b[1], a[2] - b[2]}; }
inline double dot(const Vec3& a, const Vec3& b) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }
inline Vec3 cross(const Vec3& a, const Vec3& b) {
    return {a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]};
}

inline double point_segment_sq_distance(const Vec3& p, const Vec3& a, const Vec3& b) {
    const Vec3 ab = sub(b, a);
    const double length_sq = dot(ab, ab);
    const double t = length_sq > 0 ? std::clamp(dot(sub(p, a), ab) / length_sq, 0.0, 1.0) : 0.0;
    const Vec3 closest{a[0] + t * ab[0], a[1] + t * ab[1], a[2] + t * ab[2]};
    const Vec3 d = sub(p, closest);
    return dot(d, d);
}

/// Exact squared distance from p to triangle abc: the plane distance when p projects inside,
/// otherwise the distance to the nearest edge.
inline double point_triangle_sq_distance(const Vec3& p, const Vec3& a, const Vec3& b,
                                         const Vec3& c) {
    const Vec3 n = cross(sub(b, a), sub(c, a));
    const double n_sq = dot(n, n);
    if (n_sq > 0) {
        const double h = dot(sub(p, a), n) / n_sq;
        const Vec3 q{p[0] - h * n[0], p[1] - h * n[1], p[2] - h * n[2]};
        if (dot(cross(sub(b, a), sub(q, a)), n) >= 0 && dot(cross(sub(c, b), sub(q, b)), n) >= 0 &&
            dot(cross(sub(a, c), sub(q, c)), n) >= 0)
            return h * h * n_sq;
    }
    return std::min({point_segment_sq_distance(p, a, b), point_segment_sq_distance(p, b, c),
                     point_segment_sq_distance(p, c, a)});
}

inline Vec3 vertex(const TriangleMesh& mesh, int64_t face, int corner) {
    const int64_t v = mesh.faces[face][corner].item<int64_t>();
    auto xyz = mesh.vertices.accessor<float, 2>();
    return {xyz[v][0], xyz[v][1], xyz[v][2]};
}

/// Index of the face nearest to p and its distance (brute force over all faces).
inline std::pair<int64_t, double> nearest_face(const TriangleMesh& mesh, const Vec3& p) {
    std::pair<int64_t, double> best{-1, std::numeric_limits<double>::infinity()};
    for (int64_t f = 0; f < mesh.num_faces(); ++f) {
        const double d = point_triangle_sq_distance(p, vertex(mesh, f, 0), vertex(mesh, f, 1),
                                                    vertex(mesh, f, 2));
        if (d < best.second) best = {f, d};
    }
    best.second = std::sqrt(best.second);
    return best;
}

/// Unit normal of a face from its winding.
inline Vec3 face_normal(const TriangleMesh& mesh, int64_t face) {
    const Vec3 a = vertex(mesh, face, 0);
    const Vec3 n = cross(sub(vertex(mesh, face, 1), a), sub(vertex(mesh, face, 2), a));
    const double length = std::sqrt(dot(n, n));
    return {n[0] / length, n[1] / length, n[2] / length};
}

/// The cube [-0.5, 0.5]^3 as 12 triangles wound counter-clockwise seen from outside.
inline TriangleMesh unit_cube() {
    std::vector<float> vertices;
    for (int i = 0; i < 8; ++i)
        for (int axis = 2; axis >= 0; --axis) vertices.push_back((i >> axis & 1) ? 0.5f : -0.5f);
    // Vertex i has x = bit 2, y = bit 1, z = bit 0.
    std::vector<int64_t> faces;
    for (int axis = 0; axis < 3; ++axis)
        for (int side = 0; side < 2; ++side) {
            const int bit = 2 - axis, u = (bit + 1) % 3, v = (bit + 2) % 3;
            const int base = side << bit;
            int quad[4] = {base, base | 1 << u, base | 1 << u | 1 << v, base | 1 << v};
            // The u and v edges span the face with u x v along -axis: reverse the loop on the
            // positive side.
            if (side == 1) std::swap(quad[1], quad[3]);
            faces.insert(faces.end(), {quad[0], quad[1], quad[2], quad[0], quad[2], quad[3]});
        }
    return {at::tensor(vertices).view({8, 3}), at::tensor(faces).view({12, 3})};
}

}  // namespace pumeta::test
