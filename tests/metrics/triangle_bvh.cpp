// Point-to-triangle distance against analytic and dense-sampling oracles; the BVH and P2F
// against brute force over all triangles.
#include "pumeta/metrics/triangle_bvh.h"

#include <ATen/ATen.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <random>
#include <vector>

#include "pumeta/core/error.h"
#include "pumeta/geometry/sampling.h"
#include "pumeta/metrics/metrics.h"
#include "support/test_util.h"

namespace pumeta {
namespace {

using Vec = std::array<double, 3>;

Vec operator+(const Vec& a, const Vec& b) { return {a[0] + b[0], a[1] + b[1], a[2] + b[2]}; }
Vec operator-(const Vec& a, const Vec& b) { return {a[0] - b[0], a[1] - b[1], a[2] - b[2]}; }
Vec operator*(double s, const Vec& a) { return {s * a[0], s * a[1], s * a[2]}; }
double dot(const Vec& a, const Vec& b) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }
double norm(const Vec& a) { return std::sqrt(dot(a, a)); }
Vec unit(const Vec& a) { return (1 / norm(a)) * a; }
Vec cross(const Vec& a, const Vec& b) {
    return {a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]};
}

double distance(const Vec& p, const Vec& a, const Vec& b, const Vec& c) {
    return point_triangle_distance(p.data(), a.data(), b.data(), c.data());
}

struct Triangle {
    Vec a, b, c;
};

/// Oracle: the minimum distance over a dense barycentric grid of (n+1)(n+2)/2 samples. Every
/// point of the triangle lies within (longest edge)/n of a sample, which bounds how much
/// the sampled minimum can exceed the true distance.
struct SampledDistance {
    double min;
    double resolution;
};

SampledDistance sampled_distance(const Vec& p, const Triangle& t, int n) {
    double best = std::numeric_limits<double>::infinity();
    for (int i = 0; i <= n; ++i) {
        for (int j = 0; i + j <= n; ++j) {
            double u = double(i) / n, v = double(j) / n;
            best = std::min(best, norm(p - (t.a + u * (t.b - t.a) + v * (t.c - t.a))));
        }
    }
    double longest = std::max({norm(t.b - t.a), norm(t.c - t.a), norm(t.c - t.b)});
    return {best, longest / n};
}

void expect_matches_sampling(const Vec& p, const Triangle& t) {
    SampledDistance sampled = sampled_distance(p, t, 200);
    double d = distance(p, t.a, t.b, t.c);
    // Never farther than a point of the triangle, never closer than the sampling allows.
    EXPECT_LE(d, sampled.min + 1e-12);
    EXPECT_GE(d, sampled.min - sampled.resolution);
}

Vec random_vec(std::mt19937_64& rng, double lo, double hi) {
    std::uniform_real_distribution<double> uniform(lo, hi);
    return {uniform(rng), uniform(rng), uniform(rng)};
}

// For each random triangle, query points are built in each Voronoi region (face, the three
// edges, the three vertices) at a distance known by construction, and checked against that
// distance and against dense sampling.
TEST(PointTriangleDistance, MatchesAnalyticDistanceAndSamplingInEveryRegion) {
    std::mt19937_64 rng(42);
    std::uniform_real_distribution<double> uniform(0, 1);
    for (int trial = 0; trial < 30; ++trial) {
        Triangle t{random_vec(rng, -1, 1), random_vec(rng, -1, 1), random_vec(rng, -1, 1)};
        const std::array<Vec, 3> corner = {t.a, t.b, t.c};
        Vec normal = unit(cross(t.b - t.a, t.c - t.a));
        double height = 2 * uniform(rng) - 1;  // signed offset along the normal
        SCOPED_TRACE(testing::Message() << "trial " << trial);

        // Face: above an interior point, the distance is the height.
        double u = 0.05 + 0.6 * uniform(rng), v = 0.05 + (0.9 - u) * uniform(rng);
        Vec on_face = t.a + u * (t.b - t.a) + v * (t.c - t.a);
        Vec p = on_face + height * normal;
        EXPECT_NEAR(distance(p, t.a, t.b, t.c), std::abs(height), 1e-12);
        expect_matches_sampling(p, t);

        for (int k = 0; k < 3; ++k) {
            const Vec& x = corner[k];
            const Vec& y = corner[(k + 1) % 3];
            const Vec& z = corner[(k + 2) % 3];
            // Edge xy: beyond the edge's line, in the plane, away from z, and within the
            // edge's span; the closest point is the foot on the edge.
            Vec outward = unit(cross(y - x, normal));
            if (dot(outward, z - x) > 0) outward = -1 * outward;
            double along = 0.05 + 0.9 * uniform(rng), off = 0.01 + uniform(rng);
            p = x + along * (y - x) + off * outward + height * normal;
            EXPECT_NEAR(distance(p, t.a, t.b, t.c), std::hypot(off, height), 1e-12);
            expect_matches_sampling(p, t);

            // Vertex x: any direction making an obtuse angle with both edges from x.
            Vec w = (-(0.01 + uniform(rng))) * (unit(y - x) + unit(z - x)) + height * normal;
            p = x + w;
            EXPECT_NEAR(distance(p, t.a, t.b, t.c), norm(w), 1e-12);
            expect_matches_sampling(p, t);
        }

        // Anywhere around the triangle.
        for (int k = 0; k < 5; ++k) expect_matches_sampling(random_vec(rng, -2, 2), t);
    }
}

/// Independent oracle for degenerate triangles: distance to the segment [a, b].
double segment_distance(const Vec& p, const Vec& a, const Vec& b) {
    Vec ab = b - a;
    double t = dot(ab, ab) > 0 ? std::clamp(dot(p - a, ab) / dot(ab, ab), 0.0, 1.0) : 0.0;
    return norm(p - (a + t * ab));
}

TEST(PointTriangleDistance, DegenerateTrianglesBehaveAsSegmentsOrPoints) {
    std::mt19937_64 rng(7);
    for (int trial = 0; trial < 50; ++trial) {
        Vec a = random_vec(rng, -1, 1), b = random_vec(rng, -1, 1);
        Vec p = random_vec(rng, -2, 2);
        SCOPED_TRACE(testing::Message() << "trial " << trial);
        // All three corners equal: a point.
        EXPECT_NEAR(distance(p, a, a, a), norm(p - a), 1e-12);
        // Two corners equal, in every position: the segment between the distinct ones.
        EXPECT_NEAR(distance(p, a, a, b), segment_distance(p, a, b), 1e-12);
        EXPECT_NEAR(distance(p, a, b, a), segment_distance(p, a, b), 1e-12);
        EXPECT_NEAR(distance(p, b, a, a), segment_distance(p, a, b), 1e-12);
        // Collinear, the third corner between the others or beyond them: the hull segment.
        Vec middle = a + 0.3 * (b - a), beyond = a + 1.7 * (b - a);
        EXPECT_NEAR(distance(p, a, b, middle), segment_distance(p, a, b), 1e-12);
        EXPECT_NEAR(distance(p, middle, a, b), segment_distance(p, a, b), 1e-12);
        EXPECT_NEAR(distance(p, a, b, beyond), segment_distance(p, a, beyond), 1e-12);
        // A sliver one part in 1e10 wide: within that of its long edge.
        Vec sliver = middle + 1e-10 * random_vec(rng, -1, 1);
        EXPECT_NEAR(distance(p, a, b, sliver), segment_distance(p, a, b), 1e-9);
        for (double value :
             {distance(p, a, a, b), distance(p, a, b, middle), distance(p, a, b, sliver)})
            EXPECT_TRUE(std::isfinite(value));
    }
}

/// A mesh of `num_faces` random triangles, some sharing vertices, plus degenerate ones: repeated
/// indices, collinear corners, and many copies of one triangle (identical centroids).
TriangleMesh random_mesh(int64_t num_faces, uint64_t seed) {
    const int64_t num_vertices = num_faces / 2 + 8;
    at::Tensor vertices = uniform_random_points(num_vertices, seed);
    std::mt19937_64 rng(seed);
    std::uniform_int_distribution<int64_t> pick(0, num_vertices - 1);
    std::vector<int64_t> faces;
    for (int64_t f = 0; f < num_faces; ++f) {
        for (int corner = 0; corner < 3; ++corner) faces.push_back(pick(rng));
    }
    // Collinear: vertex 2 on the segment from vertex 0 to vertex 1.
    vertices[2].copy_(vertices[0] * 0.25 + vertices[1] * 0.75);
    for (int64_t f : {0, 1, 2, 1, 1, 3, 4, 4, 4}) faces.push_back(f);
    for (int copy = 0; copy < 20; ++copy) {
        for (int64_t f : {5, 6, 7}) faces.push_back(f);
    }
    return {vertices, at::tensor(faces, at::kLong).view({-1, 3})};
}

std::vector<double> brute_force_mesh_distances(const TriangleMesh& mesh,
                                               const at::Tensor& queries) {
    at::Tensor v = mesh.vertices.to(at::kDouble).contiguous();
    at::Tensor q = queries.to(at::kDouble).contiguous();
    auto vs = v.accessor<double, 2>();
    auto fs = mesh.faces.accessor<int64_t, 2>();
    auto qs = q.accessor<double, 2>();
    std::vector<double> result(q.size(0), std::numeric_limits<double>::infinity());
    for (int64_t i = 0; i < q.size(0); ++i) {
        Vec p = {qs[i][0], qs[i][1], qs[i][2]};
        for (int64_t f = 0; f < mesh.faces.size(0); ++f) {
            auto vertex = [&](int corner) {
                int64_t index = fs[f][corner];
                return Vec{vs[index][0], vs[index][1], vs[index][2]};
            };
            result[i] = std::min(result[i], distance(p, vertex(0), vertex(1), vertex(2)));
        }
    }
    return result;
}

// The brute force uses point_triangle_distance too (checked above against independent
// oracles): what this test checks is the hierarchy's pruning.
TEST(TriangleBvh, MatchesBruteForceOverAllTriangles) {
    const TriangleMesh single_triangle{uniform_random_points(3, 99),
                                       at::tensor({0, 1, 2}, at::kLong).view({1, 3})};
    for (const TriangleMesh& mesh : {single_triangle, random_mesh(5, 105), random_mesh(300, 400)}) {
        // Queries near the mesh, far from it, and on the corners of its triangles.
        at::Tensor corners = mesh.vertices.index_select(0, mesh.faces.flatten());
        at::Tensor queries = at::cat(
            {uniform_random_points(400, 3) * 1.5f, uniform_random_points(20, 4) * 10.f, corners});
        at::Tensor d = TriangleBvh(mesh).distances(queries);
        ASSERT_EQ(d.scalar_type(), at::kDouble);
        ASSERT_EQ(d.size(0), queries.size(0));
        std::vector<double> expected = brute_force_mesh_distances(mesh, queries);
        for (int64_t i = 0; i < queries.size(0); ++i)
            ASSERT_NEAR(d[i].item<double>(), expected[i], 1e-12)
                << "query " << i << " of " << mesh.num_faces() << " triangles";
        for (int64_t i = queries.size(0) - corners.size(0); i < queries.size(0); ++i)
            EXPECT_NEAR(d[i].item<double>(), 0.0, 1e-12);
    }
}

TEST(TriangleBvh, AcceptsNoQueriesAndRejectsBadMeshes) {
    TriangleMesh mesh = random_mesh(10, 1);
    EXPECT_EQ(TriangleBvh(mesh).distances(at::empty({0, 3})).size(0), 0);
    EXPECT_THROW(TriangleBvh(mesh).distances(at::zeros({3, 2})), InputError);
    EXPECT_THROW(TriangleBvh({mesh.vertices, mesh.faces + mesh.num_vertices()}), InputError);
    EXPECT_THROW(TriangleBvh({mesh.vertices, at::empty({0, 3}, at::kLong)}), InputError);
    EXPECT_THROW(TriangleBvh({mesh.vertices, mesh.faces.to(at::kInt)}), InputError);
}

/// Oracle for first_hit: the smallest positive crossing over all triangles, by plane
/// intersection and a barycentric inside test (independent of Möller–Trumbore).
double brute_force_first_hit(const TriangleMesh& mesh, const Vec& o, const Vec& d, double max_t) {
    at::Tensor v = mesh.vertices.to(at::kDouble);
    double best = std::numeric_limits<double>::infinity();
    for (int64_t f = 0; f < mesh.num_faces(); ++f) {
        Vec corner[3];
        for (int k = 0; k < 3; ++k) {
            at::Tensor row = v[mesh.faces[f][k].item<int64_t>()];
            corner[k] = {row[0].item<double>(), row[1].item<double>(), row[2].item<double>()};
        }
        Vec n = cross(corner[1] - corner[0], corner[2] - corner[0]);
        double denom = dot(n, d);
        if (std::abs(denom) < 1e-14) continue;
        double t = dot(n, corner[0] - o) / denom;
        if (t <= 0 || t > max_t) continue;
        Vec p = o + t * d;
        // Inside when p is on the inner side of all three edges (same sign as n).
        bool inside = true;
        for (int k = 0; k < 3; ++k)
            if (dot(cross(corner[(k + 1) % 3] - corner[k], p - corner[k]), n) < -1e-12)
                inside = false;
        if (inside) best = std::min(best, t);
    }
    return best;
}

TEST(TriangleBvhRay, HitsAKnownPlaneAtTheKnownRange) {
    // The square [-10, 10]^2 at z = 0; a ray from (1, 2, 3) going down at 45 degrees in x.
    TriangleMesh square{
        at::tensor({-10.f, -10.f, 0.f, 10.f, -10.f, 0.f, 10.f, 10.f, 0.f, -10.f, 10.f, 0.f})
            .view({4, 3}),
        at::tensor({0, 1, 2, 0, 2, 3}, at::kLong).view({2, 3})};
    TriangleBvh bvh(square);
    const double o[3] = {1, 2, 3};
    const double down45[3] = {std::sqrt(0.5), 0, -std::sqrt(0.5)};
    EXPECT_NEAR(bvh.first_hit(o, down45, 100), 3 * std::sqrt(2.0), 1e-12);
    const double down[3] = {0, 0, -2};  // not unit: t in its units
    EXPECT_NEAR(bvh.first_hit(o, down, 100), 1.5, 1e-12);
    EXPECT_TRUE(std::isinf(bvh.first_hit(o, down45, 4.0)));  // beyond max_t
    const double up[3] = {0, 0, 1};
    EXPECT_TRUE(std::isinf(bvh.first_hit(o, up, 100)));  // away from the plane
    const double along[3] = {1, 0, 0};
    EXPECT_TRUE(std::isinf(bvh.first_hit(o, along, 100)));  // parallel
    const double below[3] = {0, 0, -1};
    EXPECT_NEAR(bvh.first_hit(below, up, 100), 1.0, 1e-12);  // from the back side
    // Through the diagonal the two triangles share, at many points: never a gap.
    for (int i = 0; i < 200; ++i) {
        const double x = -9.5 + 19.0 * i / 199;
        const double on_edge[3] = {x, x, 0.7};
        const double slanted[3] = {0.1, -0.3, -0.7};  // hits (x + 0.1, x - 0.3): off the edge
        EXPECT_NEAR(bvh.first_hit(on_edge, down, 100), 0.35, 1e-12) << x;
        EXPECT_NEAR(bvh.first_hit(on_edge, slanted, 100), 1.0, 1e-12) << x;
    }
}

TEST(TriangleBvhRay, MatchesBruteForceFirstHits) {
    const TriangleMesh mesh = random_mesh(300, 400);
    TriangleBvh bvh(mesh);
    at::Tensor origins = uniform_random_points(300, 5).to(at::kDouble) * 2.0;
    at::Tensor directions = uniform_random_points(300, 6).to(at::kDouble);
    at::Tensor hits = bvh.first_hits(origins, directions, 50.0);
    ASSERT_EQ(hits.scalar_type(), at::kDouble);
    int64_t hit_count = 0;
    for (int64_t i = 0; i < origins.size(0); ++i) {
        Vec o = {origins[i][0].item<double>(), origins[i][1].item<double>(),
                 origins[i][2].item<double>()};
        Vec d = {directions[i][0].item<double>(), directions[i][1].item<double>(),
                 directions[i][2].item<double>()};
        double expected = brute_force_first_hit(mesh, o, d, 50.0);
        double got = hits[i].item<double>();
        if (std::isinf(expected)) {
            EXPECT_TRUE(std::isinf(got)) << "ray " << i << ": " << got;
        } else {
            ++hit_count;
            EXPECT_NEAR(got, expected, 1e-9) << "ray " << i;
        }
    }
    EXPECT_GT(hit_count, 30);  // the rays start among the triangles: many hit (49 here)
    EXPECT_THROW(bvh.first_hits(origins, directions.narrow(0, 0, 10), 1.0), InputError);
    EXPECT_THROW(bvh.first_hits(origins, at::zeros({300, 2}), 1.0), InputError);
}

// The unit square at z = 0 as two triangles. Points: (0.5, 0.5, 0.25) above it (0.25),
// (2, 0.5, 0) beside edge x = 1 (1), (0.2, 0.3, 0) on it (0), (-3, -4, 0) beyond the corner
// (0,0) (5). Mean = (0.25 + 1 + 0 + 5) / 4 = 1.5625.
TEST(PointToFaceDistance, HandComputedSquare) {
    TriangleMesh square{
        at::tensor({0.f, 0.f, 0.f, 1.f, 0.f, 0.f, 1.f, 1.f, 0.f, 0.f, 1.f, 0.f}).view({4, 3}),
        at::tensor({0, 1, 2, 0, 2, 3}, at::kLong).view({2, 3})};
    at::Tensor pred =
        at::tensor({0.5f, 0.5f, 0.25f, 2.f, 0.5f, 0.f, 0.2f, 0.3f, 0.f, -3.f, -4.f, 0.f})
            .view({4, 3});
    EXPECT_DOUBLE_EQ(point_to_face_distance(pred, square), 1.5625);
}

TEST(PointToFaceDistance, IsTheMeanOfBruteForceDistances) {
    TriangleMesh mesh = random_mesh(200, 9);
    at::Tensor pred = uniform_random_points(300, 10);
    std::vector<double> expected = brute_force_mesh_distances(mesh, pred);
    double mean = 0;
    for (double d : expected) mean += d / expected.size();
    EXPECT_NEAR(point_to_face_distance(pred, mesh), mean, 1e-12);
    EXPECT_THROW(point_to_face_distance(at::empty({0, 3}), mesh), InputError);
}

}  // namespace
}  // namespace pumeta
