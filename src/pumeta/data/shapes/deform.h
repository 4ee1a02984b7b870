// Smooth global deformations that turn the generator's regular parts into less regular shapes.
// Within the documented limits each map has a Jacobian of positive determinant, so a closed,
// outward-oriented mesh stays closed and outward.
#pragma once

#include "pumeta/data/shapes/mesh.h"
#include "pumeta/data/shapes/random.h"

namespace pumeta::shapes {

/// Taper, twist and bend along one axis, applied in that order. The position along the axis is
/// s in [-1, 1] across the mesh's bounding box.
struct Deformation {
    /// The deformation axis: 0 = x, 1 = y, 2 = z.
    int axis = 2;
    /// The cross-section is scaled by 1 + taper * s; |taper| < 1.
    double taper = 0;
    /// The cross-section is rotated by twist * s radians about the axis.
    double twist = 0;
    /// The axis is bent into a circular arc turning by bend * s radians at s, towards the next
    /// axis in x-y-z order. Needs |bend| * r < L, where L is the box's half extent along the
    /// axis and r the largest distance of a (tapered) point from it.
    double bend = 0;
};

/// A random deformation for `mesh`: each of taper (|taper| <= 0.3), twist (|twist| <= 0.5)
/// and bend (|bend| <= 0.5, and |bend| * r <= L / 2) present with probability 1/2.
Deformation random_deformation(Rng& rng, const Mesh& mesh);

/// The mesh with `deformation` applied.
Mesh deformed(Mesh mesh, const Deformation& deformation);

/// A rotation uniformly distributed over SO(3) (Shoemake's unit quaternion from three uniforms).
Mat3 random_rotation(Rng& rng);

/// The mesh translated to centre its bounding box at the origin and scaled so that its
/// farthest vertex is at distance 1.
Mesh fit_unit_sphere(Mesh mesh);

}  // namespace pumeta::shapes
