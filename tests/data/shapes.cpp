#include "pumeta/data/shapes.h"

#include <ATen/ATen.h>
#include <gtest/gtest.h>

#include <cmath>
#include <map>
#include <numeric>
#include <set>

#include "pumeta/core/error.h"
#include "pumeta/data/shapes/deform.h"
#include "pumeta/data/shapes/primitives.h"

namespace pumeta {

namespace {

using shapes::Mesh;
using shapes::Vec2;
using shapes::Vec3;

/// What the closedness checks found; empty `problem` when the mesh is a union of closed,
/// consistently oriented components.
struct Audit {
    std::string problem;
    std::vector<double> component_volumes;
};

/// Independent of the generator: edges by sorting, components by union-find, volumes by the
/// divergence theorem (sum of signed tetrahedra against the origin).
Audit audit(const TriangleMesh& mesh) {
    Audit result;
    at::Tensor vertices = mesh.vertices.to(at::kDouble).contiguous();
    at::Tensor faces = mesh.faces.contiguous();
    int64_t nv = vertices.size(0), nf = faces.size(0);
    const double* v = vertices.data_ptr<double>();
    const int64_t* f = faces.data_ptr<int64_t>();
    if (nf == 0) return {"no faces", {}};
    for (int64_t i = 0; i < 3 * nv; ++i)
        if (!std::isfinite(v[i])) return {"non-finite vertex coordinate", {}};
    std::vector<std::pair<int64_t, int64_t>> edges;
    std::vector<int64_t> parent(nv);
    std::iota(parent.begin(), parent.end(), 0);
    auto find = [&](int64_t x) {
        while (parent[x] != x) x = parent[x] = parent[parent[x]];
        return x;
    };
    for (int64_t t = 0; t < nf; ++t) {
        const int64_t* c = f + 3 * t;
        for (int k = 0; k < 3; ++k)
            if (c[k] < 0 || c[k] >= nv) return {"face index out of range", {}};
        if (c[0] == c[1] || c[1] == c[2] || c[0] == c[2])
            return {"face " + std::to_string(t) + " repeats a vertex", {}};
        Vec3 a{v[3 * c[0]], v[3 * c[0] + 1], v[3 * c[0] + 2]};
        Vec3 b{v[3 * c[1]], v[3 * c[1] + 1], v[3 * c[1] + 2]};
        Vec3 d{v[3 * c[2]], v[3 * c[2] + 1], v[3 * c[2] + 2]};
        if (!(norm(cross(b - a, d - a)) > 1e-14))
            return {"face " + std::to_string(t) + " is degenerate", {}};
        for (int k = 0; k < 3; ++k) {
            edges.push_back({c[k], c[(k + 1) % 3]});
            parent[find(c[k])] = find(c[(k + 1) % 3]);
        }
    }
    // Closed and consistently oriented: every directed edge occurs once and so does its
    // reverse (so each undirected edge is used by exactly two faces).
    std::sort(edges.begin(), edges.end());
    for (size_t i = 0; i < edges.size(); ++i) {
        if (i + 1 < edges.size() && edges[i] == edges[i + 1])
            return {"directed edge used twice (inconsistent orientation or non-manifold)", {}};
        if (!std::binary_search(edges.begin(), edges.end(),
                                std::pair{edges[i].second, edges[i].first}))
            return {"boundary edge (hole)", {}};
    }
    std::map<int64_t, double> volume;
    for (int64_t t = 0; t < nf; ++t) {
        const int64_t* c = f + 3 * t;
        Vec3 a{v[3 * c[0]], v[3 * c[0] + 1], v[3 * c[0] + 2]};
        Vec3 b{v[3 * c[1]], v[3 * c[1] + 1], v[3 * c[1] + 2]};
        Vec3 d{v[3 * c[2]], v[3 * c[2] + 1], v[3 * c[2] + 2]};
        volume[find(c[0])] += dot(a, cross(b, d)) / 6;
    }
    for (const auto& [root, vol] : volume) result.component_volumes.push_back(vol);
    return result;
}

double total_volume(const Mesh& mesh) {
    Audit a = audit(shapes::to_triangle_mesh(mesh));
    EXPECT_EQ(a.problem, "");
    return std::accumulate(a.component_volumes.begin(), a.component_volumes.end(), 0.0);
}

void expect_closed_outward(const Mesh& mesh, const std::string& what) {
    Audit a = audit(shapes::to_triangle_mesh(mesh));
    EXPECT_EQ(a.problem, "") << what;
    EXPECT_EQ(a.component_volumes.size(), 1u) << what;
    for (double vol : a.component_volumes) EXPECT_GT(vol, 0) << what;
}

}  // namespace

TEST(ShapePrimitives, VolumesMatchClosedForms) {
    shapes::Tessellation tess{0.05};
    // Flat faces are exact.
    EXPECT_NEAR(total_volume(shapes::rounded_box({0.5, 0.3, 0.2}, 0, tess)), 8 * 0.5 * 0.3 * 0.2,
                1e-6);
    // A prism over a regular n-gon: n/2 sin(2 pi/n) r^2 h.
    int n = tess.around(0.4);
    EXPECT_NEAR(total_volume(shapes::frustum(0.4, 0.4, 1.5, tess)),
                n / 2.0 * std::sin(2 * M_PI / n) * 0.16 * 1.5, 1e-5);
    EXPECT_NEAR(total_volume(shapes::extrude(shapes::regular_polygon(6, 1.0), 0.5, tess)),
                3 * std::sqrt(3.0) / 2 * 0.5, 1e-5);
    // Curved surfaces are inscribed polyhedra: a little smaller than the smooth solid.
    auto near_below = [](double tessellated, double exact) {
        EXPECT_LT(tessellated, exact * 1.0005);
        EXPECT_GT(tessellated, exact * 0.97);
    };
    near_below(total_volume(shapes::uv_sphere(1, tess)), 4 * M_PI / 3);
    near_below(total_volume(shapes::icosphere(1, 4)), 4 * M_PI / 3);
    near_below(total_volume(shapes::torus(1, 0.3, tess)), 2 * M_PI * M_PI * 0.09);
    near_below(total_volume(shapes::capsule(0.3, 1, tess)), M_PI * 0.09 + 4 * M_PI / 3 * 0.027);
    near_below(total_volume(shapes::tube(0.2, 0.5, 0.7, tess)), M_PI * (0.25 - 0.04) * 0.7);
    near_below(total_volume(shapes::frustum(0.5, 0.2, 1, tess)), M_PI / 3 * (0.25 + 0.1 + 0.04));
    // Rounded box = inner box dilated by a ball (Steiner's formula).
    double a = 0.4, b = 0.3, c = 0.2, r = 0.1;
    near_below(total_volume(shapes::rounded_box({a + r, b + r, c + r}, r, tess)),
               8 * a * b * c + 8 * (a * b + b * c + a * c) * r + 2 * M_PI * (a + b + c) * r * r +
                   4 * M_PI / 3 * r * r * r);
    // A superquadric with both exponents 1 is an ellipsoid.
    near_below(total_volume(shapes::superquadric({1, 0.5, 0.7}, 1, 1, tess)), 4 * M_PI / 3 * 0.35);
}

TEST(ShapePrimitives, EachIsClosedAndOutward) {
    shapes::Tessellation tess{0.07};
    std::vector<Vec2> gear = shapes::gear_outline(17, 0.8, 0.95);
    std::vector<Vec2> ell{{0, 0}, {1, 0}, {1, 0.2}, {0.2, 0.2}, {0.2, 1}, {0, 1}};
    expect_closed_outward(shapes::rounded_box({1, 0.5, 0.2}, 0.15, tess), "rounded box");
    expect_closed_outward(shapes::frustum(0.5, 0, 1, tess), "cone");
    expect_closed_outward(shapes::superquadric({1, 0.6, 0.4}, 0.3, 1.8, tess), "superquadric");
    expect_closed_outward(shapes::extrude(shapes::refine_polyline(ell, 0.1, true), 0.4, tess),
                          "L prism");
    expect_closed_outward(
        shapes::extrude_ring(gear, shapes::circle_at_angles(gear, 0.2), 0.3, tess), "gear");
    expect_closed_outward(shapes::lathe_loop({{0.2, 0}, {0.5, 0}, {0.6, 0.5}, {0.3, 0.3}}, 12),
                          "revolved loop");
}

TEST(ShapePrimitives, EarClippingCoversThePolygonWithCounterClockwiseTriangles) {
    shapes::Rng rng(7);
    for (int trial = 0; trial < 400; ++trial) {
        // Star-shaped polygons with collinear points inserted on their edges (which puts
        // vertices on diagonals, within rounding).
        std::vector<Vec2> polygon;
        int n = rng.integer(3, 16);
        for (int k = 0; k < n; ++k) {
            double angle = 2 * M_PI * (k + rng.uniform(0.1, 0.9)) / n, r = rng.uniform(0.2, 1);
            polygon.push_back({r * std::cos(angle), r * std::sin(angle)});
        }
        polygon = shapes::refine_polyline(polygon, rng.uniform(0.05, 0.5), true);
        double area = 0;
        for (size_t i = 0; i < polygon.size(); ++i) {
            const Vec2 &p = polygon[i], &q = polygon[(i + 1) % polygon.size()];
            area += (p.x * q.y - q.x * p.y) / 2;
        }
        auto triangles = shapes::ear_clip(polygon);
        ASSERT_EQ(triangles.size(), polygon.size() - 2);
        double covered = 0;
        for (const auto& [a, b, c] : triangles) {
            const Vec2 &p = polygon[a], &q = polygon[b], &s = polygon[c];
            double twice = (q.x - p.x) * (s.y - p.y) - (q.y - p.y) * (s.x - p.x);
            EXPECT_GT(twice, 0);
            covered += twice / 2;
        }
        EXPECT_NEAR(covered, area, 1e-12);
    }
    EXPECT_THROW(shapes::ear_clip({{0, 0}, {0, 1}, {1, 0}}), InputError);  // clockwise
}

TEST(ShapeDeformations, ActAsDocumented) {
    Mesh mesh = shapes::rounded_box({0.3, 0.2, 1}, 0, {0.1});
    // Twist about z keeps every vertex's distance to the axis and its height.
    shapes::Deformation twist;
    twist.twist = 0.5;
    Mesh twisted = shapes::deformed(mesh, twist);
    for (size_t i = 0; i < mesh.vertices.size(); ++i) {
        const Vec3 &p = mesh.vertices[i], &q = twisted.vertices[i];
        EXPECT_NEAR(std::hypot(p.x, p.y), std::hypot(q.x, q.y), 1e-12);
        EXPECT_DOUBLE_EQ(p.z, q.z);
        // At the top (s = 1) the rotation is exactly `twist`.
        if (p.z == 1) {
            double turned = std::atan2(q.y, q.x) - std::atan2(p.y, p.x);
            EXPECT_NEAR(std::remainder(turned, 2 * M_PI), 0.5, 1e-9);
        }
    }
    // Taper scales the cross-section by 1 + taper * s.
    shapes::Deformation taper;
    taper.taper = 0.25;
    Mesh tapered = shapes::deformed(mesh, taper);
    for (size_t i = 0; i < mesh.vertices.size(); ++i) {
        double s = mesh.vertices[i].z;
        EXPECT_NEAR(tapered.vertices[i].x, mesh.vertices[i].x * (1 + 0.25 * s), 1e-12);
    }
    // Bend keeps the arc length of the axis: the axis' top end moves to the circle of radius
    // L / bend, turned by `bend`.
    shapes::Deformation bend;
    bend.bend = 0.4;
    Mesh axis;
    axis.vertices = {{0, 0, -1}, {0, 0, 1}, {0.3, 0, 0}, {-0.3, 0, 0}};
    Mesh bent = shapes::deformed(axis, bend);
    double radius = 1 / 0.4;
    EXPECT_NEAR(bent.vertices[1].x, radius - radius * std::cos(0.4), 1e-12);
    EXPECT_NEAR(bent.vertices[1].z, radius * std::sin(0.4), 1e-12);
    // Deformations are orientation-preserving: the volume stays positive and close.
    for (const auto& d : {twist, taper, bend}) {
        double before = total_volume(mesh), after = total_volume(shapes::deformed(mesh, d));
        EXPECT_GT(after, 0.7 * before);
    }
}

TEST(ShapeDeformations, RandomRotationIsARotation) {
    shapes::Rng rng(3);
    for (int trial = 0; trial < 20; ++trial) {
        shapes::Mat3 r = shapes::random_rotation(rng);
        for (int i = 0; i < 3; ++i)
            for (int j = 0; j < 3; ++j) {
                double d = 0;
                for (int k = 0; k < 3; ++k) d += r.m[3 * i + k] * r.m[3 * j + k];
                EXPECT_NEAR(d, i == j ? 1 : 0, 1e-12);
            }
        Vec3 x{r.m[0], r.m[3], r.m[6]}, y{r.m[1], r.m[4], r.m[7]}, z{r.m[2], r.m[5], r.m[8]};
        EXPECT_NEAR(dot(cross(x, y), z), 1, 1e-12);
    }
    Vec3 d = shapes::normalized({1, -2, 0.5});
    Vec3 mapped = shapes::rotation_from_z(d) * Vec3{0, 0, 1};
    EXPECT_NEAR(norm(mapped - d), 0, 1e-12);
    mapped = shapes::rotation_from_z({0, 0, -1}) * Vec3{0, 0, 1};
    EXPECT_NEAR(mapped.z, -1, 1e-12);
}

TEST(GenerateShape, ManySeedsGiveClosedOutwardComponentsOfEveryKind) {
    std::map<std::string, int> kinds, categories;
    for (uint64_t seed = 0; seed < 200; ++seed) {
        TriangleMesh mesh = generate_shape(seed);
        std::string kind = shape_kind(seed);
        ASSERT_EQ(mesh.vertices.scalar_type(), at::kFloat);
        ASSERT_EQ(mesh.faces.scalar_type(), at::kLong);
        ASSERT_EQ(mesh.vertices.dim(), 2);
        ASSERT_EQ(mesh.vertices.size(1), 3);
        ASSERT_EQ(mesh.faces.size(1), 3);
        Audit a = audit(mesh);
        ASSERT_EQ(a.problem, "") << "seed " << seed << " (" << kind << ")";
        for (double vol : a.component_volumes)
            ASSERT_GT(vol, 0) << "seed " << seed << " (" << kind << ")";
        // Normalised: the farthest vertex at distance 1 from the bounding box centre (0).
        EXPECT_NEAR(mesh.vertices.norm(2, 1).max().item<double>(), 1, 1e-5);
        at::Tensor lo = std::get<0>(mesh.vertices.min(0)), hi = std::get<0>(mesh.vertices.max(0));
        EXPECT_LT((lo + hi).abs().max().item<double>(), 1e-5);
        ++kinds[kind];
        ++categories[shape_category(kind)];
    }
    for (const std::string& kind : shape_kinds()) EXPECT_GT(kinds[kind], 0) << kind;
    for (const std::string& category : shape_categories())
        EXPECT_GT(categories[category], 30) << category;
}

TEST(GenerateShape, SameSeedGivesIdenticalMeshAndForcedKindAgrees) {
    for (uint64_t seed : {0ull, 5ull, 123456789ull}) {
        TriangleMesh first = generate_shape(seed), second = generate_shape(seed);
        EXPECT_TRUE(at::equal(first.vertices, second.vertices));
        EXPECT_TRUE(at::equal(first.faces, second.faces));
        ShapeOptions forced;
        forced.kind = shape_kind(seed);
        TriangleMesh third = generate_shape(seed, forced);
        EXPECT_TRUE(at::equal(first.vertices, third.vertices));
        EXPECT_TRUE(at::equal(first.faces, third.faces));
    }
    TriangleMesh a = generate_shape(1), b = generate_shape(2);
    EXPECT_FALSE(a.vertices.sizes() == b.vertices.sizes() && at::equal(a.vertices, b.vertices));
}

TEST(GenerateShape, EveryKindIsClosedWithoutDeformationAndFurnitureStandsUpright) {
    ShapeOptions options;
    options.deform = false;
    options.rotate = false;
    options.normalize = false;
    for (const std::string& kind : shape_kinds()) {
        options.kind = kind;
        for (uint64_t seed = 0; seed < 5; ++seed) {
            TriangleMesh mesh = generate_shape(seed, options);
            EXPECT_EQ(shape_kind(seed, options), kind);
            Audit a = audit(mesh);
            ASSERT_EQ(a.problem, "") << kind << " seed " << seed;
            for (double vol : a.component_volumes) EXPECT_GT(vol, 0) << kind << " seed " << seed;
            if (shape_category(kind) == "furniture") {
                // Built in metres standing on the floor, +y up once not rotated.
                at::Tensor y = mesh.vertices.select(1, 1);
                EXPECT_NEAR(y.min().item<double>(), 0, 1e-6) << kind;
                EXPECT_GT(y.max().item<double>(), 0.3) << kind;
            }
        }
    }
}

TEST(GenerateShape, ResolutionControlsTriangleCount) {
    ShapeOptions coarse, fine;
    coarse.kind = fine.kind = "torus";
    fine.resolution = 2;
    int64_t few = generate_shape(4, coarse).num_faces();
    int64_t many = generate_shape(4, fine).num_faces();
    EXPECT_GT(many, 3 * few);  // both directions of the surface get finer
    for (uint64_t seed = 0; seed < 60; ++seed) {
        int64_t faces = generate_shape(seed).num_faces();
        EXPECT_GE(faces, 100) << seed;
        EXPECT_LE(faces, 10000) << seed;
    }
}

TEST(GenerateShape, RejectsUnknownNamesAndBadResolution) {
    ShapeOptions options;
    options.kind = "spaceship";
    EXPECT_THROW(generate_shape(0, options), InputError);
    options.kind.clear();
    options.category = "vehicles";
    EXPECT_THROW(generate_shape(0, options), InputError);
    options.category = "mechanical";
    EXPECT_EQ(shape_category(shape_kind(0, options)), "mechanical");
    options.resolution = 0;
    EXPECT_THROW(generate_shape(0, options), InputError);
    EXPECT_THROW(shape_category("spaceship"), InputError);
}

}  // namespace pumeta
