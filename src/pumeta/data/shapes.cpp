#include "pumeta/data/shapes.h"

#include <algorithm>
#include <array>
#include <cmath>

#include "pumeta/core/error.h"
#include "pumeta/data/shapes/assemblies.h"
#include "pumeta/data/shapes/deform.h"
#include "pumeta/data/shapes/primitives.h"

namespace pumeta {

namespace {

using shapes::Mesh;
using shapes::Rng;
using shapes::Tessellation;
using shapes::Vec2;
using shapes::Vec3;

// The primitives get random proportions here; `detail` is the edge length relative to the
// shape's largest dimension, as for the assemblies.

Mesh make_box(Rng& rng, double detail) {
    Vec3 half{rng.uniform(0.3, 1.0), rng.uniform(0.3, 1.0), rng.uniform(0.3, 1.0)};
    return shapes::rounded_box(half, 0, {detail * 2 * std::max({half.x, half.y, half.z})});
}

Mesh make_rounded_box(Rng& rng, double detail) {
    Vec3 half{rng.uniform(0.3, 1.0), rng.uniform(0.3, 1.0), rng.uniform(0.3, 1.0)};
    double radius = std::min({half.x, half.y, half.z}) * rng.uniform(0.08, 0.6);
    return shapes::rounded_box(half, radius, {detail * 2 * std::max({half.x, half.y, half.z})});
}

Mesh make_cylinder(Rng& rng, double detail) {
    double radius = rng.uniform(0.2, 0.8), height = rng.uniform(0.3, 2.0);
    return shapes::frustum(radius, radius, height, {detail * std::max(2 * radius, height)});
}

Mesh make_cone(Rng& rng, double detail) {
    double bottom = rng.uniform(0.3, 0.9), height = rng.uniform(0.4, 1.8);
    double top = rng.chance(0.4) ? 0 : bottom * rng.uniform(0.1, 0.8);
    return shapes::frustum(bottom, top, height, {detail * std::max(2 * bottom, height)});
}

Mesh make_sphere(Rng& rng, double detail) {
    Vec3 radii{rng.uniform(0.5, 1.0), rng.uniform(0.5, 1.0), rng.uniform(0.5, 1.0)};
    Mesh sphere;
    if (rng.chance(0.5)) {
        sphere = shapes::uv_sphere(1, {detail * 2});
    } else {
        // A level-k icosphere of radius 1 has edges of about 1.05 / 2^k.
        double level = std::round(std::log2(1.05 / (detail * 2)));
        sphere = shapes::icosphere(1, static_cast<int>(std::clamp(level, 1.0, 5.0)));
    }
    return shapes::scaled(std::move(sphere), radii);
}

Mesh make_torus(Rng& rng, double detail) {
    double minor = rng.uniform(0.15, 0.5);
    return shapes::torus(1, minor, {detail * 2 * (1 + minor)});
}

Mesh make_capsule(Rng& rng, double detail) {
    double radius = rng.uniform(0.2, 0.5), length = rng.uniform(0.2, 1.5);
    return shapes::capsule(radius, length, {detail * (length + 2 * radius)});
}

Mesh make_superquadric(Rng& rng, double detail) {
    Vec3 radii{rng.uniform(0.5, 1.0), rng.uniform(0.5, 1.0), rng.uniform(0.5, 1.0)};
    double e1 = rng.uniform(0.25, 2.0), e2 = rng.uniform(0.25, 2.0);
    return shapes::superquadric(radii, e1, e2, {detail * 2});
}

/// A random simple polygon, star-shaped about the origin (vertices at increasing angles): a
/// sharp star of few vertices or a smooth blob whose radius is a low-order Fourier series.
std::vector<Vec2> random_star_polygon(Rng& rng) {
    std::vector<Vec2> polygon;
    if (rng.chance(0.5)) {
        int n = rng.integer(5, 16);
        for (int k = 0; k < n; ++k) {
            // Jittered within its own sector, so the angles stay increasing.
            double angle = 2 * M_PI * (k + rng.uniform(0.2, 0.8)) / n;
            double r = rng.uniform(0.35, 1.0);
            polygon.push_back({r * std::cos(angle), r * std::sin(angle)});
        }
        return polygon;
    }
    std::array<double, 3> amplitude, phase;
    for (int m = 0; m < 3; ++m) {
        amplitude[m] = rng.uniform(0.0, 0.3) / (m + 1);
        phase[m] = rng.uniform(0.0, 2 * M_PI);
    }
    const int n = 64;
    for (int k = 0; k < n; ++k) {
        double angle = 2 * M_PI * k / n;
        double r = 1;  // at least 1 - 0.3 - 0.15 - 0.1 > 0
        for (int m = 0; m < 3; ++m) r += amplitude[m] * std::cos((m + 2) * angle + phase[m]);
        polygon.push_back({r * std::cos(angle), r * std::sin(angle)});
    }
    return polygon;
}

Mesh make_extrusion(Rng& rng, double detail) {
    double height = rng.uniform(0.2, 1.5);
    Tessellation tess{detail * 2};
    std::vector<Vec2> polygon = random_star_polygon(rng);
    return shapes::extrude(shapes::refine_polyline(polygon, 2 * tess.edge, true), height, tess);
}

Mesh make_revolved(Rng& rng, double detail) {
    double height = rng.uniform(1.0, 2.0), radius = rng.uniform(0.3, 0.7);
    Tessellation tess{detail * std::max(height, 2 * radius)};
    std::vector<Vec2> profile = shapes::random_profile(rng, height, radius, rng.integer(3, 8), 0.2);
    return shapes::lathe(shapes::refine_polyline(profile, 2 * tess.edge, false),
                         tess.around(radius));
}

struct Kind {
    const char* name;
    const char* category;
    Mesh (*build)(Rng&, double detail);
};

const std::vector<Kind>& kinds() {
    static const std::vector<Kind> table{
        {"box", "primitive", make_box},
        {"rounded_box", "primitive", make_rounded_box},
        {"cylinder", "primitive", make_cylinder},
        {"cone", "primitive", make_cone},
        {"sphere", "primitive", make_sphere},
        {"torus", "primitive", make_torus},
        {"capsule", "primitive", make_capsule},
        {"superquadric", "primitive", make_superquadric},
        {"extrusion", "primitive", make_extrusion},
        {"revolved", "primitive", make_revolved},
        {"table", "furniture", shapes::make_table},
        {"chair", "furniture", shapes::make_chair},
        {"shelf", "furniture", shapes::make_shelf},
        {"cabinet", "furniture", shapes::make_cabinet},
        {"lamp", "furniture", shapes::make_lamp},
        {"sofa", "furniture", shapes::make_sofa},
        {"gear", "mechanical", shapes::make_gear},
        {"flange", "mechanical", shapes::make_flange},
        {"bracket", "mechanical", shapes::make_bracket},
        {"shaft", "mechanical", shapes::make_shaft},
        {"pulley", "mechanical", shapes::make_pulley},
        {"bearing_block", "mechanical", shapes::make_bearing_block},
    };
    return table;
}

const Kind& find_kind(const std::string& name) {
    for (const Kind& kind : kinds())
        if (name == kind.name) return kind;
    throw_input_error("", "unknown shape kind '{}'", name);
}

const Kind& choose_kind(uint64_t seed, const ShapeOptions& options) {
    if (!options.kind.empty()) return find_kind(options.kind);
    const auto& categories = shape_categories();
    if (!options.category.empty() &&
        std::find(categories.begin(), categories.end(), options.category) == categories.end())
        throw_input_error("", "unknown shape category '{}'", options.category);
    Rng rng(seed);
    std::string category = options.category.empty()
                               ? categories[rng.integer(0, static_cast<int>(categories.size()) - 1)]
                               : options.category;
    std::vector<const Kind*> members;
    for (const Kind& kind : kinds())
        if (category == kind.category) members.push_back(&kind);
    return *members[rng.integer(0, static_cast<int>(members.size()) - 1)];
}

/// SplitMix64's finaliser: the parameters' stream must differ from the one choosing the kind.
uint64_t mix(uint64_t x) {
    x += 0x9e3779b97f4a7c15ULL;
    x = (x ^ (x >> 30)) * 0xbf58476d1ce4e5b9ULL;
    x = (x ^ (x >> 27)) * 0x94d049bb133111ebULL;
    return x ^ (x >> 31);
}

}  // namespace

TriangleMesh generate_shape(uint64_t seed, const ShapeOptions& options) {
    if (!(options.resolution > 0 && options.resolution <= 8))
        throw_input_error("", "shape resolution must be in (0, 8], got {}", options.resolution);
    const Kind& kind = choose_kind(seed, options);
    // Parameters come from their own stream, so that forcing the kind a seed would pick
    // reproduces the same shape.
    Rng rng(mix(seed));
    Mesh mesh = kind.build(rng, 0.05 / options.resolution);
    if (options.deform) {
        shapes::Deformation deformation = shapes::random_deformation(rng, mesh);
        mesh = shapes::deformed(std::move(mesh), deformation);
        Vec3 factors;
        for (double* f : {&factors.x, &factors.y, &factors.z})
            *f = std::exp(rng.uniform(std::log(0.75), std::log(1.33)));
        mesh = shapes::scaled(std::move(mesh), factors);
    }
    // The builders work with z up.
    shapes::Mat3 turn =
        options.rotate ? shapes::random_rotation(rng) : shapes::rotation({1, 0, 0}, -M_PI / 2);
    mesh = shapes::transformed(std::move(mesh), turn, {0, 0, 0});
    if (options.normalize) mesh = shapes::fit_unit_sphere(std::move(mesh));
    return shapes::to_triangle_mesh(mesh);
}

std::string shape_kind(uint64_t seed, const ShapeOptions& options) {
    return choose_kind(seed, options).name;
}

const std::vector<std::string>& shape_kinds() {
    static const std::vector<std::string> names = [] {
        std::vector<std::string> all;
        for (const Kind& kind : kinds()) all.push_back(kind.name);
        return all;
    }();
    return names;
}

const std::vector<std::string>& shape_categories() {
    static const std::vector<std::string> names{"primitive", "furniture", "mechanical"};
    return names;
}

std::string shape_category(const std::string& kind) { return find_kind(kind).category; }

}  // namespace pumeta
