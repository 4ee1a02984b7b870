// The double-precision mesh that the shape generator assembles parts in, with the small
// vector algebra it needs. Converted to the float32 TriangleMesh only once a shape is done,
// so that placing and deforming parts never accumulates float rounding.
#pragma once

#include <array>
#include <cmath>
#include <cstdint>
#include <vector>

#include "pumeta/geometry/point_cloud.h"

namespace pumeta::shapes {

struct Vec2 {
    double x = 0, y = 0;
};

struct Vec3 {
    double x = 0, y = 0, z = 0;
};

inline Vec3 operator+(Vec3 a, Vec3 b) { return {a.x + b.x, a.y + b.y, a.z + b.z}; }
inline Vec3 operator-(Vec3 a, Vec3 b) { return {a.x - b.x, a.y - b.y, a.z - b.z}; }
inline Vec3 operator*(Vec3 a, double s) { return {a.x * s, a.y * s, a.z * s}; }
inline double dot(Vec3 a, Vec3 b) { return a.x * b.x + a.y * b.y + a.z * b.z; }
inline Vec3 cross(Vec3 a, Vec3 b) {
    return {a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x};
}
inline double norm(Vec3 a) { return std::sqrt(dot(a, a)); }
inline Vec3 normalized(Vec3 a) { return a * (1.0 / norm(a)); }

/// Row-major 3x3 matrix.
struct Mat3 {
    std::array<double, 9> m{1, 0, 0, 0, 1, 0, 0, 0, 1};

    Vec3 operator*(Vec3 v) const {
        return {m[0] * v.x + m[1] * v.y + m[2] * v.z, m[3] * v.x + m[4] * v.y + m[5] * v.z,
                m[6] * v.x + m[7] * v.y + m[8] * v.z};
    }
};

/// Rotation by `angle` radians about the unit vector `axis` (right-handed).
Mat3 rotation(Vec3 axis, double angle);

/// A rotation taking +z to the unit vector `direction` (the parts built along +z, such as
/// lathe solids and extrusions, are placed with it).
Mat3 rotation_from_z(Vec3 direction);

/// A triangle mesh under construction. Faces are counter-clockwise seen from outside.
struct Mesh {
    std::vector<Vec3> vertices;
    std::vector<std::array<int64_t, 3>> faces;

    int64_t add_vertex(Vec3 v) {
        vertices.push_back(v);
        return static_cast<int64_t>(vertices.size()) - 1;
    }
    void add_triangle(int64_t a, int64_t b, int64_t c) { faces.push_back({a, b, c}); }
    /// Two triangles a-b-c and a-c-d of the quad a-b-c-d.
    void add_quad(int64_t a, int64_t b, int64_t c, int64_t d) {
        add_triangle(a, b, c);
        add_triangle(a, c, d);
    }
    /// Adds the vertices and faces of `other` (its faces re-indexed).
    void append(const Mesh& other);
};

/// Lowest and highest corner of the axis-aligned bounding box; the mesh must have vertices.
std::array<Vec3, 2> bounding_box(const Mesh& mesh);

/// p -> rotation * p + translation. Only rotations keep faces outward, hence no general matrix.
Mesh transformed(Mesh mesh, const Mat3& rotation, Vec3 translation);

/// p -> p + offset.
Mesh translated(Mesh mesh, Vec3 offset);

/// p -> p * factors (component-wise); factors must be positive so that faces stay outward.
Mesh scaled(Mesh mesh, Vec3 factors);

/// The float32/int64 tensor form.
TriangleMesh to_triangle_mesh(const Mesh& mesh);

}  // namespace pumeta::shapes
