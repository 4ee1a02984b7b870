#include "pumeta/data/shapes/deform.h"

#include <algorithm>
#include <array>
#include <cmath>

namespace pumeta::shapes {

namespace {

double& coordinate(Vec3& v, int axis) { return axis == 0 ? v.x : axis == 1 ? v.y : v.z; }

}  // namespace

Deformation random_deformation(Rng& rng, const Mesh& mesh) {
    Deformation d;
    d.axis = rng.integer(0, 2);
    if (rng.chance(0.5)) d.taper = rng.uniform(-0.3, 0.3);
    if (rng.chance(0.5)) d.twist = rng.uniform(-0.5, 0.5);
    if (rng.chance(0.5)) {
        auto [lo, hi] = bounding_box(mesh);
        Vec3 half = (hi - lo) * 0.5;
        double length = coordinate(half, d.axis);
        double reach =
            std::hypot(coordinate(half, (d.axis + 1) % 3), coordinate(half, (d.axis + 2) % 3)) *
            (1 + std::abs(d.taper));
        // Keeps the bend's Jacobian determinant 1 - bend * x / L at least 1/2.
        double limit = std::min(0.5, 0.5 * length / reach);
        d.bend = rng.sign() * rng.uniform(0.2, 1.0) * limit;
    }
    return d;
}

Mesh deformed(Mesh mesh, const Deformation& deformation) {
    auto [lo, hi] = bounding_box(mesh);
    Vec3 centre = (lo + hi) * 0.5;
    // (u, v, w) is a cyclic permutation of (x, y, z) with w the deformation axis, so the maps
    // below written for (x, y, z) keep their orientation.
    int w = deformation.axis, u = (w + 1) % 3, v = (w + 2) % 3;
    double length = (coordinate(hi, w) - coordinate(lo, w)) / 2;
    for (Vec3& p : mesh.vertices) {
        double x = coordinate(p, u) - coordinate(centre, u);
        double y = coordinate(p, v) - coordinate(centre, v);
        double z = coordinate(p, w) - coordinate(centre, w);
        double s = z / length;
        double scale = 1 + deformation.taper * s;
        x *= scale;
        y *= scale;
        double angle = deformation.twist * s;
        double c = std::cos(angle), sn = std::sin(angle);
        double xt = c * x - sn * y;
        y = sn * x + c * y;
        x = xt;
        if (deformation.bend != 0) {
            // The axis becomes an arc of radius L / bend (same length); a point at distance x
            // from it moves to radius L / bend - x.
            double arc_radius = length / deformation.bend;
            double turn = z / arc_radius;
            double radius = arc_radius - x;
            x = arc_radius - radius * std::cos(turn);
            z = radius * std::sin(turn);
        }
        coordinate(p, u) = coordinate(centre, u) + x;
        coordinate(p, v) = coordinate(centre, v) + y;
        coordinate(p, w) = coordinate(centre, w) + z;
    }
    return mesh;
}

Mat3 random_rotation(Rng& rng) {
    double u1 = rng.uniform(), u2 = rng.uniform(), u3 = rng.uniform();
    double a = std::sqrt(1 - u1), b = std::sqrt(u1);
    double qx = a * std::sin(2 * M_PI * u2), qy = a * std::cos(2 * M_PI * u2);
    double qz = b * std::sin(2 * M_PI * u3), qw = b * std::cos(2 * M_PI * u3);
    Mat3 r;
    r.m = {1 - 2 * (qy * qy + qz * qz), 2 * (qx * qy - qz * qw),     2 * (qx * qz + qy * qw),
           2 * (qx * qy + qz * qw),     1 - 2 * (qx * qx + qz * qz), 2 * (qy * qz - qx * qw),
           2 * (qx * qz - qy * qw),     2 * (qy * qz + qx * qw),     1 - 2 * (qx * qx + qy * qy)};
    return r;
}

Mesh fit_unit_sphere(Mesh mesh) {
    auto [lo, hi] = bounding_box(mesh);
    Vec3 centre = (lo + hi) * 0.5;
    double radius = 0;
    for (const Vec3& p : mesh.vertices) radius = std::max(radius, norm(p - centre));
    double scale = radius > 0 ? 1 / radius : 1;
    for (Vec3& p : mesh.vertices) p = (p - centre) * scale;
    return mesh;
}

}  // namespace pumeta::shapes
