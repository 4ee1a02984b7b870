#include "pumeta/data/shapes/primitives.h"

#include <algorithm>
#include <cmath>
#include <map>

#include "pumeta/core/error.h"

namespace pumeta::shapes {

namespace {

constexpr double kPi = M_PI;

double cross2(Vec2 o, Vec2 a, Vec2 b) {
    return (a.x - o.x) * (b.y - o.y) - (a.y - o.y) * (b.x - o.x);
}

double signed_area(const std::vector<Vec2>& polygon) {
    double twice = 0;
    for (size_t i = 0; i < polygon.size(); ++i) {
        const Vec2& a = polygon[i];
        const Vec2& b = polygon[(i + 1) % polygon.size()];
        twice += a.x * b.y - b.x * a.y;
    }
    return twice / 2;
}

void require_ccw(const std::vector<Vec2>& polygon, const char* what) {
    if (polygon.size() < 3 || !(signed_area(polygon) > 0))
        throw_input_error("", "{}: needs a counter-clockwise polygon of at least 3 vertices", what);
}

/// Joins consecutive rings of `segments` vertices each, or single pole vertices, into a band of
/// quads (triangles at poles); with `closed` the last ring joins the first. Rings must wind
/// counter-clockwise about +z and follow each other counter-clockwise in the (r, z) half plane
/// for the faces to point outward.
void stitch_rings(Mesh& mesh, const std::vector<int64_t>& ring_start, const std::vector<bool>& pole,
                  int segments, bool closed) {
    size_t rings = ring_start.size();
    size_t bands = closed ? rings : rings - 1;
    for (size_t i = 0; i < bands; ++i) {
        size_t next = (i + 1) % rings;
        if (pole[i] && pole[next])
            throw_input_error("", "lathe profile has two consecutive points on the axis");
        for (int j = 0; j < segments; ++j) {
            int jn = (j + 1) % segments;
            int64_t a = ring_start[i] + (pole[i] ? 0 : j);
            int64_t b = ring_start[i] + (pole[i] ? 0 : jn);
            int64_t c = ring_start[next] + (pole[next] ? 0 : jn);
            int64_t d = ring_start[next] + (pole[next] ? 0 : j);
            if (pole[i])
                mesh.add_triangle(a, c, d);
            else if (pole[next])
                mesh.add_triangle(a, b, c);
            else
                mesh.add_quad(a, b, c, d);
        }
    }
}

Mesh revolve(const std::vector<Vec2>& profile, int segments, bool closed) {
    if (segments < 3) throw_input_error("", "lathe needs at least 3 segments, got {}", segments);
    if (profile.size() < 3) throw_input_error("", "lathe profile needs at least 3 points");
    std::vector<double> cosines(segments), sines(segments);
    for (int j = 0; j < segments; ++j) {
        double angle = 2 * kPi * j / segments;
        cosines[j] = std::cos(angle);
        sines[j] = std::sin(angle);
    }
    Mesh mesh;
    std::vector<int64_t> ring_start;
    std::vector<bool> pole;
    for (size_t i = 0; i < profile.size(); ++i) {
        Vec2 p = profile[i];
        bool end = i == 0 || i + 1 == profile.size();
        bool on_axis = !closed && end;
        if (on_axis ? p.x != 0 : !(p.x > 0))
            throw_input_error(
                "", "lathe profile point {} has r = {}: {}", i, p.x,
                closed ? "loops need r > 0" : "profiles run from r = 0 to r = 0 through r > 0");
        ring_start.push_back(static_cast<int64_t>(mesh.vertices.size()));
        pole.push_back(on_axis);
        if (on_axis) {
            mesh.add_vertex({0, 0, p.y});
            continue;
        }
        for (int j = 0; j < segments; ++j) mesh.add_vertex({p.x * cosines[j], p.x * sines[j], p.y});
    }
    stitch_rings(mesh, ring_start, pole, segments, closed);
    return mesh;
}

/// Grid coordinates along one axis of a rounded box: a uniform flat middle and, with a radius,
/// bands whose nodes project to equal angles (tan spacing) on the rounded edge.
std::vector<double> box_nodes(double half, double radius, const Tessellation& tess) {
    double flat = half - radius;
    int middle = tess.along(2 * flat);
    int band = radius > 0 ? std::max(2, tess.around(radius) / 8) : 0;
    std::vector<double> nodes;
    for (int k = band; k >= 1; --k)
        nodes.push_back(-(flat + radius * std::tan(kPi / 4 * k / band)));
    for (int k = 0; k <= middle; ++k) nodes.push_back(-flat + 2 * flat * k / middle);
    nodes[band + middle] = flat;
    for (int k = 1; k <= band; ++k) nodes.push_back(flat + radius * std::tan(kPi / 4 * k / band));
    return nodes;
}

/// Merges vertices with bitwise equal coordinates (the shared borders of separately built
/// grids); vertices keep the order of their first occurrence.
Mesh weld_identical(const Mesh& mesh) {
    std::map<std::array<double, 3>, int64_t> index;
    std::vector<int64_t> remap(mesh.vertices.size());
    Mesh welded;
    for (size_t i = 0; i < mesh.vertices.size(); ++i) {
        const Vec3& v = mesh.vertices[i];
        auto [it, inserted] =
            index.emplace(std::array<double, 3>{v.x, v.y, v.z}, welded.vertices.size());
        if (inserted) welded.vertices.push_back(v);
        remap[i] = it->second;
    }
    for (const auto& f : mesh.faces) welded.add_triangle(remap[f[0]], remap[f[1]], remap[f[2]]);
    return welded;
}

}  // namespace

int Tessellation::around(double radius) const {
    double segments = std::ceil(2 * kPi * radius / edge);
    return static_cast<int>(std::clamp(segments, 8.0, 128.0));
}

int Tessellation::along(double length) const {
    double divisions = std::ceil(length / (2 * edge));
    return static_cast<int>(std::clamp(divisions, 1.0, 64.0));
}

Mesh rounded_box(Vec3 half_extents, double radius, const Tessellation& tess) {
    std::array<double, 3> half{half_extents.x, half_extents.y, half_extents.z};
    if (!(radius >= 0) || !(radius < *std::min_element(half.begin(), half.end())))
        throw_input_error("", "rounded box radius {} must be in [0, smallest half extent)", radius);
    std::array<std::vector<double>, 3> nodes;
    for (int a = 0; a < 3; ++a) nodes[a] = box_nodes(half[a], radius, tess);

    Mesh grid;
    for (int a = 0; a < 3; ++a) {
        // (u, v, a) is a cyclic permutation of (x, y, z), so e_u x e_v = e_a.
        int u = (a + 1) % 3, v = (a + 2) % 3;
        for (double side : {-1.0, 1.0}) {
            double fixed = side > 0 ? nodes[a].back() : nodes[a].front();
            auto base = static_cast<int64_t>(grid.vertices.size());
            int nu = static_cast<int>(nodes[u].size()), nv = static_cast<int>(nodes[v].size());
            for (int i = 0; i < nu; ++i) {
                for (int j = 0; j < nv; ++j) {
                    std::array<double, 3> p;
                    p[a] = fixed;
                    p[u] = nodes[u][i];
                    p[v] = nodes[v][j];
                    grid.add_vertex({p[0], p[1], p[2]});
                }
            }
            for (int i = 0; i + 1 < nu; ++i) {
                for (int j = 0; j + 1 < nv; ++j) {
                    int64_t p00 = base + i * nv + j, p10 = p00 + nv, p11 = p10 + 1, p01 = p00 + 1;
                    if (side > 0)
                        grid.add_quad(p00, p10, p11, p01);
                    else
                        grid.add_quad(p00, p01, p11, p10);
                }
            }
        }
    }
    Mesh mesh = weld_identical(grid);
    if (radius == 0) return mesh;
    // Each point of the box surface moves to the rounded surface along the direction from the
    // nearest point of the inner box (the box shrunk by the radius).
    for (Vec3& p : mesh.vertices) {
        Vec3 inner{std::clamp(p.x, -half[0] + radius, half[0] - radius),
                   std::clamp(p.y, -half[1] + radius, half[1] - radius),
                   std::clamp(p.z, -half[2] + radius, half[2] - radius)};
        p = inner + normalized(p - inner) * radius;
    }
    return mesh;
}

Mesh lathe(const std::vector<Vec2>& profile, int segments) {
    return revolve(profile, segments, false);
}

Mesh lathe_loop(const std::vector<Vec2>& loop, int segments) {
    if (!(signed_area(loop) > 0)) throw_input_error("", "lathe loop must be counter-clockwise");
    return revolve(loop, segments, true);
}

Mesh frustum(double bottom_radius, double top_radius, double height, const Tessellation& tess) {
    double h = height / 2;
    std::vector<Vec2> profile{{0, -h}, {bottom_radius, -h}};
    if (top_radius > 0) profile.push_back({top_radius, h});
    profile.push_back({0, h});
    return lathe(refine_polyline(profile, 2 * tess.edge, false),
                 tess.around(std::max(bottom_radius, top_radius)));
}

Mesh uv_sphere(double radius, const Tessellation& tess) {
    int segments = tess.around(radius);
    int rings = std::max(3, segments / 2);
    std::vector<Vec2> profile{{0, -radius}};
    for (int k = 1; k < rings; ++k) {
        double polar = kPi * k / rings;
        profile.push_back({radius * std::sin(polar), -radius * std::cos(polar)});
    }
    profile.push_back({0, radius});
    return lathe(profile, segments);
}

Mesh icosphere(double radius, int subdivisions) {
    // The 12 vertices (0, +-1, +-g), (+-1, +-g, 0), (+-g, 0, +-1) of an icosahedron with edge 2;
    // its faces are the vertex triples at mutual distance 2, turned to face outward.
    const double g = (1 + std::sqrt(5.0)) / 2;
    Mesh mesh;
    for (double s : {-1.0, 1.0}) {
        for (double t : {-g, g}) {
            mesh.add_vertex({0, s, t});
            mesh.add_vertex({s, t, 0});
            mesh.add_vertex({t, 0, s});
        }
    }
    auto is_edge = [&](int i, int j) {
        Vec3 d = mesh.vertices[i] - mesh.vertices[j];
        return std::abs(dot(d, d) - 4) < 1e-9;
    };
    for (int i = 0; i < 12; ++i)
        for (int j = i + 1; j < 12; ++j)
            for (int k = j + 1; k < 12; ++k) {
                if (!is_edge(i, j) || !is_edge(j, k) || !is_edge(i, k)) continue;
                const auto& v = mesh.vertices;
                bool outward = dot(cross(v[j] - v[i], v[k] - v[i]), v[i] + v[j] + v[k]) > 0;
                outward ? mesh.add_triangle(i, j, k) : mesh.add_triangle(i, k, j);
            }
    for (int level = 0; level < subdivisions; ++level) {
        std::map<std::pair<int64_t, int64_t>, int64_t> midpoint;
        auto split = [&](int64_t a, int64_t b) {
            auto key = std::minmax(a, b);
            auto it = midpoint.find(key);
            if (it != midpoint.end()) return it->second;
            int64_t m = mesh.add_vertex((mesh.vertices[a] + mesh.vertices[b]) * 0.5);
            midpoint.emplace(key, m);
            return m;
        };
        std::vector<std::array<int64_t, 3>> faces;
        for (const auto& [a, b, c] : mesh.faces) {
            int64_t ab = split(a, b), bc = split(b, c), ca = split(c, a);
            faces.push_back({a, ab, ca});
            faces.push_back({ab, b, bc});
            faces.push_back({ca, bc, c});
            faces.push_back({ab, bc, ca});
        }
        mesh.faces = std::move(faces);
    }
    for (Vec3& v : mesh.vertices) v = normalized(v) * radius;
    return mesh;
}

Mesh torus(double major_radius, double minor_radius, const Tessellation& tess) {
    if (!(minor_radius > 0 && minor_radius < major_radius))
        throw_input_error("", "torus needs 0 < minor radius < major radius");
    int minor_segments = tess.around(minor_radius);
    std::vector<Vec2> loop;
    for (int k = 0; k < minor_segments; ++k) {
        double angle = 2 * kPi * k / minor_segments;
        loop.push_back(
            {major_radius + minor_radius * std::cos(angle), minor_radius * std::sin(angle)});
    }
    return lathe_loop(loop, tess.around(major_radius + minor_radius));
}

Mesh capsule(double radius, double length, const Tessellation& tess) {
    int quarter = std::max(2, tess.around(radius) / 4);
    double h = length / 2;
    std::vector<Vec2> profile{{0, -h - radius}};
    for (int k = 1; k <= quarter; ++k) {
        double angle = kPi / 2 * k / quarter;
        profile.push_back({radius * std::sin(angle), -h - radius * std::cos(angle)});
    }
    for (int k = 0; k < quarter; ++k) {
        double angle = kPi / 2 * k / quarter;
        profile.push_back({radius * std::cos(angle), h + radius * std::sin(angle)});
    }
    profile.push_back({0, h + radius});
    return lathe(refine_polyline(profile, 2 * tess.edge, false), tess.around(radius));
}

Mesh tube(double inner_radius, double outer_radius, double height, const Tessellation& tess) {
    if (!(inner_radius > 0 && inner_radius < outer_radius))
        throw_input_error("", "tube needs 0 < inner radius < outer radius");
    double h = height / 2;
    std::vector<Vec2> loop{
        {inner_radius, -h}, {outer_radius, -h}, {outer_radius, h}, {inner_radius, h}};
    return lathe_loop(refine_polyline(loop, 2 * tess.edge, true), tess.around(outer_radius));
}

Mesh superquadric(Vec3 radii, double e1, double e2, const Tessellation& tess) {
    if (!(e1 > 0 && e1 <= 4 && e2 > 0 && e2 <= 4))
        throw_input_error("", "superquadric exponents must be in (0, 4], got {} and {}", e1, e2);
    // Signed power keeps the octant of each coordinate.
    auto spow = [](double value, double exponent) {
        return std::copysign(std::pow(std::abs(value), exponent), value);
    };
    int segments = tess.around(std::max(radii.x, radii.y));
    int rings = std::max(4, tess.around(std::max({radii.x, radii.y, radii.z})) / 2);
    Mesh mesh;
    std::vector<int64_t> ring_start;
    std::vector<bool> pole;
    for (int i = 0; i <= rings; ++i) {
        ring_start.push_back(static_cast<int64_t>(mesh.vertices.size()));
        pole.push_back(i == 0 || i == rings);
        if (pole.back()) {
            mesh.add_vertex({0, 0, i == 0 ? -radii.z : radii.z});
            continue;
        }
        double latitude = -kPi / 2 + kPi * i / rings;
        double c = spow(std::cos(latitude), e1), z = radii.z * spow(std::sin(latitude), e1);
        for (int j = 0; j < segments; ++j) {
            double longitude = 2 * kPi * j / segments;
            mesh.add_vertex({radii.x * c * spow(std::cos(longitude), e2),
                             radii.y * c * spow(std::sin(longitude), e2), z});
        }
    }
    stitch_rings(mesh, ring_start, pole, segments, false);
    return mesh;
}

Mesh extrude(const std::vector<Vec2>& polygon, double height, const Tessellation& tess) {
    require_ccw(polygon, "extrude");
    auto n = static_cast<int64_t>(polygon.size());
    int layers = tess.along(height);
    Mesh mesh;
    for (int k = 0; k <= layers; ++k) {
        double z = k == layers ? height / 2 : -height / 2 + height * k / layers;
        for (const Vec2& p : polygon) mesh.add_vertex({p.x, p.y, z});
    }
    // A side quad along a counter-clockwise edge has the outward normal edge x z.
    for (int64_t k = 0; k < layers; ++k)
        for (int64_t i = 0; i < n; ++i) {
            int64_t in = (i + 1) % n;
            mesh.add_quad(k * n + i, k * n + in, (k + 1) * n + in, (k + 1) * n + i);
        }
    int64_t top = layers * n;
    for (const auto& [a, b, c] : ear_clip(polygon)) {
        mesh.add_triangle(top + a, top + b, top + c);
        mesh.add_triangle(a, c, b);
    }
    return mesh;
}

Mesh extrude_ring(const std::vector<Vec2>& outer, const std::vector<Vec2>& inner, double height,
                  const Tessellation& tess) {
    require_ccw(outer, "extrude_ring outer loop");
    require_ccw(inner, "extrude_ring inner loop");
    if (outer.size() != inner.size())
        throw_input_error("", "extrude_ring loops differ in length: {} and {}", outer.size(),
                          inner.size());
    auto n = static_cast<int64_t>(outer.size());
    int layers = tess.along(height);
    Mesh mesh;
    for (const auto* loop : {&outer, &inner})
        for (int k = 0; k <= layers; ++k) {
            double z = k == layers ? height / 2 : -height / 2 + height * k / layers;
            for (const Vec2& p : *loop) mesh.add_vertex({p.x, p.y, z});
        }
    int64_t inner_base = (layers + 1) * n;
    auto o = [&](int64_t k, int64_t i) { return k * n + i % n; };
    auto in = [&](int64_t k, int64_t i) { return inner_base + k * n + i % n; };
    for (int64_t k = 0; k < layers; ++k)
        for (int64_t i = 0; i < n; ++i) {
            mesh.add_quad(o(k, i), o(k, i + 1), o(k + 1, i + 1), o(k + 1, i));
            // The bore's walls face the axis.
            mesh.add_quad(in(k, i), in(k + 1, i), in(k + 1, i + 1), in(k, i + 1));
        }
    for (int64_t i = 0; i < n; ++i) {
        mesh.add_quad(o(layers, i), o(layers, i + 1), in(layers, i + 1), in(layers, i));
        mesh.add_quad(o(0, i), in(0, i), in(0, i + 1), o(0, i + 1));
    }
    return mesh;
}

Mesh block(Vec3 lo, Vec3 hi, double rounding, const Tessellation& tess) {
    Vec3 half = (hi - lo) * 0.5;
    double radius = std::min(rounding, 0.9 * std::min({half.x, half.y, half.z}));
    return translated(rounded_box(half, std::max(radius, 0.0), tess), (lo + hi) * 0.5);
}

Mesh rod(Vec3 from, Vec3 to, double radius, const Tessellation& tess) {
    return placed(frustum(radius, radius, norm(to - from), tess), (from + to) * 0.5, to - from);
}

Mesh placed(Mesh part, Vec3 centre, Vec3 axis) {
    return transformed(std::move(part), rotation_from_z(normalized(axis)), centre);
}

std::vector<std::array<int, 3>> ear_clip(const std::vector<Vec2>& polygon) {
    require_ccw(polygon, "ear_clip");
    double extent = 0;
    for (const Vec2& p : polygon) extent = std::max({extent, std::abs(p.x), std::abs(p.y)});
    // Corners flatter than this are not ears (clipping them would leave slivers of zero area),
    // and vertices this close to an ear count as inside it: refined edges put vertices on
    // diagonals, where rounding could otherwise place them just outside.
    const double tolerance = 1e-12 * extent * extent;

    std::vector<int> remaining(polygon.size());
    for (size_t i = 0; i < polygon.size(); ++i) remaining[i] = static_cast<int>(i);
    std::vector<std::array<int, 3>> triangles;
    size_t start = 0;
    while (remaining.size() > 3) {
        size_t m = remaining.size();
        bool clipped = false;
        for (size_t step = 0; step < m && !clipped; ++step) {
            size_t k = (start + step) % m;
            int prev = remaining[(k + m - 1) % m], tip = remaining[k],
                next = remaining[(k + 1) % m];
            const Vec2 &a = polygon[prev], &b = polygon[tip], &c = polygon[next];
            if (cross2(a, b, c) <= tolerance) continue;
            bool empty = true;
            for (int q : remaining) {
                if (q == prev || q == tip || q == next) continue;
                const Vec2& p = polygon[q];
                if (cross2(a, b, p) >= -tolerance && cross2(b, c, p) >= -tolerance &&
                    cross2(c, a, p) >= -tolerance) {
                    empty = false;
                    break;
                }
            }
            if (!empty) continue;
            triangles.push_back({prev, tip, next});
            remaining.erase(remaining.begin() + static_cast<std::ptrdiff_t>(k));
            // Continue after the clipped ear rather than from the front, which would fan out
            // thin triangles from the first vertex.
            start = k % remaining.size();
            clipped = true;
        }
        if (!clipped) throw_input_error("", "ear_clip: polygon is not simple");
    }
    triangles.push_back({remaining[0], remaining[1], remaining[2]});
    return triangles;
}

std::vector<Vec2> refine_polyline(const std::vector<Vec2>& points, double max_length, bool closed) {
    std::vector<Vec2> refined;
    size_t n = points.size();
    size_t segments = closed ? n : n - 1;
    for (size_t i = 0; i < n; ++i) {
        refined.push_back(points[i]);
        if (i >= segments) break;
        Vec2 a = points[i], b = points[(i + 1) % n];
        double length = std::hypot(b.x - a.x, b.y - a.y);
        int pieces = static_cast<int>(std::ceil(length / max_length));
        for (int k = 1; k < pieces; ++k) {
            double t = static_cast<double>(k) / pieces;
            refined.push_back({a.x + t * (b.x - a.x), a.y + t * (b.y - a.y)});
        }
    }
    return refined;
}

std::vector<Vec2> regular_polygon(int sides, double radius, double phase) {
    std::vector<Vec2> polygon;
    for (int k = 0; k < sides; ++k) {
        double angle = phase + 2 * kPi * k / sides;
        polygon.push_back({radius * std::cos(angle), radius * std::sin(angle)});
    }
    return polygon;
}

std::vector<Vec2> gear_outline(int teeth, double root_radius, double tip_radius) {
    // Root until 1/4 of the pitch, flank, tip from 0.4 to 0.6, flank, root from 3/4.
    static const std::array<std::pair<double, bool>, 8> kSamples{{{0, false},
                                                                  {0.125, false},
                                                                  {0.25, false},
                                                                  {0.4, true},
                                                                  {0.5, true},
                                                                  {0.6, true},
                                                                  {0.75, false},
                                                                  {0.875, false}}};
    std::vector<Vec2> outline;
    for (int k = 0; k < teeth; ++k)
        for (const auto& [fraction, tip] : kSamples) {
            double angle = 2 * kPi * (k + fraction) / teeth;
            double r = tip ? tip_radius : root_radius;
            outline.push_back({r * std::cos(angle), r * std::sin(angle)});
        }
    return outline;
}

std::vector<Vec2> circle_at_angles(const std::vector<Vec2>& outline, double radius) {
    std::vector<Vec2> circle;
    for (const Vec2& p : outline) {
        double angle = std::atan2(p.y, p.x);
        circle.push_back({radius * std::cos(angle), radius * std::sin(angle)});
    }
    return circle;
}

}  // namespace pumeta::shapes
