#include "pumeta/data/shapes/mesh.h"

#include <ATen/ATen.h>

#include "pumeta/core/error.h"

namespace pumeta::shapes {

Mat3 rotation(Vec3 axis, double angle) {
    // Rodrigues: R = cI + s[k]x + (1-c) k k^T.
    double c = std::cos(angle), s = std::sin(angle), t = 1 - c;
    Vec3 k = axis;
    Mat3 r;
    r.m = {c + t * k.x * k.x,       t * k.x * k.y - s * k.z, t * k.x * k.z + s * k.y,
           t * k.y * k.x + s * k.z, c + t * k.y * k.y,       t * k.y * k.z - s * k.x,
           t * k.z * k.x - s * k.y, t * k.z * k.y + s * k.x, c + t * k.z * k.z};
    return r;
}

Mat3 rotation_from_z(Vec3 direction) {
    Vec3 z{0, 0, 1};
    Vec3 axis = cross(z, direction);
    double sine = norm(axis);
    double cosine = dot(z, direction);
    if (sine < 1e-12) {
        // Parallel: identity, or a half turn about x for -z.
        return cosine > 0 ? Mat3{} : rotation({1, 0, 0}, M_PI);
    }
    return rotation(axis * (1.0 / sine), std::atan2(sine, cosine));
}

void Mesh::append(const Mesh& other) {
    auto offset = static_cast<int64_t>(vertices.size());
    vertices.insert(vertices.end(), other.vertices.begin(), other.vertices.end());
    for (const auto& f : other.faces)
        faces.push_back({f[0] + offset, f[1] + offset, f[2] + offset});
}

std::array<Vec3, 2> bounding_box(const Mesh& mesh) {
    Vec3 lo = mesh.vertices.front(), hi = lo;
    for (const Vec3& v : mesh.vertices) {
        lo = {std::min(lo.x, v.x), std::min(lo.y, v.y), std::min(lo.z, v.z)};
        hi = {std::max(hi.x, v.x), std::max(hi.y, v.y), std::max(hi.z, v.z)};
    }
    return {lo, hi};
}

Mesh transformed(Mesh mesh, const Mat3& rotation, Vec3 translation) {
    for (Vec3& v : mesh.vertices) v = rotation * v + translation;
    return mesh;
}

Mesh translated(Mesh mesh, Vec3 offset) {
    for (Vec3& v : mesh.vertices) v = v + offset;
    return mesh;
}

Mesh scaled(Mesh mesh, Vec3 factors) {
    if (!(factors.x > 0 && factors.y > 0 && factors.z > 0))
        throw_input_error("", "scale factors must be positive (a mirror would turn faces inward)");
    for (Vec3& v : mesh.vertices) v = {v.x * factors.x, v.y * factors.y, v.z * factors.z};
    return mesh;
}

TriangleMesh to_triangle_mesh(const Mesh& mesh) {
    auto num_vertices = static_cast<int64_t>(mesh.vertices.size());
    auto num_faces = static_cast<int64_t>(mesh.faces.size());
    at::Tensor vertices = at::empty({num_vertices, 3}, at::kFloat);
    at::Tensor faces = at::empty({num_faces, 3}, at::kLong);
    float* v = vertices.data_ptr<float>();
    for (const Vec3& p : mesh.vertices) {
        *v++ = static_cast<float>(p.x);
        *v++ = static_cast<float>(p.y);
        *v++ = static_cast<float>(p.z);
    }
    int64_t* f = faces.data_ptr<int64_t>();
    for (const auto& face : mesh.faces) f = std::copy(face.begin(), face.end(), f);
    return {vertices, faces};
}

}  // namespace pumeta::shapes
