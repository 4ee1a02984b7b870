// Closed, outward-oriented primitive solids for the shape generator. Every mesh returned here
// is watertight (each edge shared by exactly two faces, traversed once in each direction) and
// centred at the origin; solids of revolution and extrusions have their axis along +z and span
// z in [-height/2, height/2].
#pragma once

#include <array>
#include <vector>

#include "pumeta/data/shapes/mesh.h"

namespace pumeta::shapes {

/// How finely curved and long surfaces are split into triangles.
struct Tessellation {
    /// Target edge length around curves, in the units of the shape; straight runs use twice
    /// this (they are split only so that bends and twists can curve them). Must be > 0.
    double edge = 0.05;

    /// Segments around a circle of `radius`: circumference / edge, within [8, 128].
    int around(double radius) const;
    /// Divisions of a straight run of `length`: length / (2 edge), within [1, 64].
    int along(double length) const;
};

/// The box [-h, h] (h = half_extents), each face a grid; with radius > 0 its edges and corners
/// are rounded with that radius (0 <= radius < min(h)).
Mesh rounded_box(Vec3 half_extents, double radius, const Tessellation& tess);

/// Revolves the profile (r, z) about the z axis with `segments` (>= 3) steps. The profile runs
/// from a pole (r = 0) up to a pole; interior points have r > 0 and become rings.
Mesh lathe(const std::vector<Vec2>& profile, int segments);

/// Revolves a closed counter-clockwise loop in the (r, z) half plane (all r > 0): a solid with
/// a hole along the axis (torus, washer, pulley).
Mesh lathe_loop(const std::vector<Vec2>& loop, int segments);

/// Circular frustum with the given bottom and top radii; top_radius = 0 makes a cone.
Mesh frustum(double bottom_radius, double top_radius, double height, const Tessellation& tess);

/// UV sphere: rings of latitude between two poles.
Mesh uv_sphere(double radius, const Tessellation& tess);

/// Icosahedron with each triangle split into 4^subdivisions, projected onto the sphere.
Mesh icosphere(double radius, int subdivisions);

/// Torus about the z axis, 0 < minor < major.
Mesh torus(double major_radius, double minor_radius, const Tessellation& tess);

/// Cylinder of `length` capped by two hemispheres of `radius` (total height length + 2 radius).
Mesh capsule(double radius, double length, const Tessellation& tess);

/// Pipe or washer: the solid between two coaxial cylinders, 0 < inner < outer.
Mesh tube(double inner_radius, double outer_radius, double height, const Tessellation& tess);

/// Superquadric |x/a|^(2/e2) ... with radii (a, b, c): latitude exponent e1 and longitude
/// exponent e2 (1 = ellipsoid, towards 0 = box-like, 2 = octahedron-like); both in (0, 4].
Mesh superquadric(Vec3 radii, double e1, double e2, const Tessellation& tess);

/// Prism over a simple counter-clockwise polygon in the xy plane; caps by ear clipping.
Mesh extrude(const std::vector<Vec2>& polygon, double height, const Tessellation& tess);

/// Prism over the region between two counter-clockwise loops of equal length, `inner` inside
/// `outer`, where vertex i of each lies on a common ray from the inner loop's interior (a gear
/// with its bore, a hexagon nut); caps are the quad strips between the loops.
Mesh extrude_ring(const std::vector<Vec2>& outer, const std::vector<Vec2>& inner, double height,
                  const Tessellation& tess);

/// The box [lo, hi] with its edges rounded by `rounding` (clamped to 0.9 of the smallest half
/// extent).
Mesh block(Vec3 lo, Vec3 hi, double rounding, const Tessellation& tess);

/// A cylinder of `radius` from point `from` to point `to`.
Mesh rod(Vec3 from, Vec3 to, double radius, const Tessellation& tess);

/// A part built along +z (lathe solids, extrusions) turned so that +z points along `axis`,
/// with its origin moved to `centre`.
Mesh placed(Mesh part, Vec3 centre, Vec3 axis = {0, 0, 1});

/// Triangulates a simple counter-clockwise polygon by ear clipping: n - 2 counter-clockwise
/// triangles of polygon indices. Collinear vertices are allowed.
std::vector<std::array<int, 3>> ear_clip(const std::vector<Vec2>& polygon);

/// The polyline with points inserted so that no segment is longer than max_length; with
/// `closed` the segment from the last point back to the first is split as well.
std::vector<Vec2> refine_polyline(const std::vector<Vec2>& points, double max_length, bool closed);

/// Regular polygon, counter-clockwise, its first vertex at angle `phase`.
std::vector<Vec2> regular_polygon(int sides, double radius, double phase = 0);

/// Outline of a spur gear with trapezoidal teeth between the two radii, counter-clockwise,
/// 8 vertices per tooth at angles 2 pi (k + f) / teeth, f in {0, 1/8, 1/4, 0.4, 1/2, 0.6,
/// 3/4, 7/8}; a circle sampled at the same angles is a matching `inner` for extrude_ring.
std::vector<Vec2> gear_outline(int teeth, double root_radius, double tip_radius);

/// Points of a circle of `radius` at the angles of `outline`'s vertices (a bore for
/// extrude_ring).
std::vector<Vec2> circle_at_angles(const std::vector<Vec2>& outline, double radius);

}  // namespace pumeta::shapes
