// The two geometry types every module exchanges. Plain tensors, one shape convention.
#pragma once

#include <ATen/core/Tensor.h>

#include <cstdint>

namespace pumeta {

/// A point cloud.
///   points:  float32 [N,3] (always defined)
///   normals: float32 [N,3] or undefined
///   colors:  uint8   [N,3] or undefined
struct PointCloud {
    at::Tensor points;
    at::Tensor normals{};
    at::Tensor colors{};

    int64_t size() const { return points.defined() ? points.size(0) : 0; }
    bool has_normals() const { return normals.defined(); }
    bool has_colors() const { return colors.defined(); }
};

/// A triangle mesh.
///   vertices: float32 [V,3]
///   faces:    int64   [F,3], indices into vertices
struct TriangleMesh {
    at::Tensor vertices;
    at::Tensor faces;

    int64_t num_vertices() const { return vertices.defined() ? vertices.size(0) : 0; }
    int64_t num_faces() const { return faces.defined() ? faces.size(0) : 0; }
};

/// What a file holds: vertices (with optional normals/colours) and, for meshes, faces.
///   faces: int64 [F,3] (polygons triangulated), undefined for pure point clouds.
struct Geometry {
    PointCloud cloud;
    at::Tensor faces;

    bool is_mesh() const { return faces.defined() && faces.size(0) > 0; }
    TriangleMesh mesh() const { return {cloud.points, faces}; }
};

}  // namespace pumeta
