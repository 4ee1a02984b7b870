// Seeded procedural CAD-like triangle meshes: primitives (box, rounded box, cylinder, cone,
// sphere, torus, capsule, superquadric, extruded polygon, solid of revolution), furniture-like
// assemblies (table, chair, shelf, cabinet, lamp, sofa) and mechanical-like assemblies (gear,
// flange, bracket, shaft, pulley, bearing block), optionally bent, twisted, tapered, scaled and
// rotated. A synthetic source of training and test meshes.
//
// Every mesh is a union of closed components: each edge is shared by exactly two faces that
// traverse it in opposite directions, and faces are counter-clockwise seen from outside
// (positive signed volume). Components of an assembly may interpenetrate.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "pumeta/geometry/point_cloud.h"

namespace pumeta {

struct ShapeOptions {
    /// Generate only this kind (one of shape_kinds()); empty = chosen by the seed.
    std::string kind;
    /// Generate only kinds of this category (one of shape_categories()); empty = any. Ignored
    /// when `kind` is set.
    std::string category;
    /// Tessellation density in (0, 8]: edge lengths scale with 1 / resolution. At 1 a primitive
    /// has about 150 to 4,000 triangles and an assembly about 250 to 8,000; counts grow about
    /// with resolution squared.
    double resolution = 1.0;
    /// Apply a random taper, twist and bend (each with probability 1/2) and a random
    /// anisotropic scale in [0.75, 1.33] per axis.
    bool deform = true;
    /// Apply a rotation uniformly distributed over SO(3). When false, +y is up (furniture
    /// stands on its feet, as in ShapeNet-style meshes).
    bool rotate = true;
    /// Centre the bounding box at the origin and scale the farthest vertex to distance 1.
    bool normalize = true;
};

/// The shape for `seed`: vertices float32 [V,3], faces int64 [F,3]. The seed picks the kind
/// (uniform over categories, then uniform over the category's kinds) and every parameter. The
/// same seed and options give a bitwise identical mesh, and forcing `options.kind` to the kind
/// a seed picks gives the same mesh. InputError for an unknown kind or category or a
/// resolution outside (0, 8].
TriangleMesh generate_shape(uint64_t seed, const ShapeOptions& options = {});

/// The kind generate_shape(seed, options) builds (cheap: nothing is built), e.g. "torus",
/// "chair", "gear"; its category is shape_category(kind).
std::string shape_kind(uint64_t seed, const ShapeOptions& options = {});

/// All kinds, grouped by category.
const std::vector<std::string>& shape_kinds();

/// "primitive", "furniture", "mechanical".
const std::vector<std::string>& shape_categories();

/// The category of a kind; InputError if the kind is unknown.
std::string shape_category(const std::string& kind);

}  // namespace pumeta
