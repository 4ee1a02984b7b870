// Sensor presets, sweep directions, the per-ray noise model and the scene layout.
#include "pumeta/data/scan_simulation.h"

#include <ATen/ATen.h>
#include <ATen/Parallel.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <random>

#include "pumeta/core/error.h"
#include "pumeta/core/hash.h"

namespace pumeta {

namespace {

constexpr double kPi = 3.14159265358979323846;
constexpr double kDegree = kPi / 180;

/// SplitMix64's finaliser: a counter-based generator, one independent stream per ray.
uint64_t mix(uint64_t x) {
    x += 0x9e3779b97f4a7c15ull;
    x = (x ^ (x >> 30)) * 0xbf58476d1ce4e5b9ull;
    x = (x ^ (x >> 27)) * 0x94d049bb133111ebull;
    return x ^ (x >> 31);
}

/// A uniform double in (0, 1) from 53 bits of mix(key).
double unit_uniform(uint64_t key) { return (static_cast<double>(mix(key) >> 11) + 0.5) * 0x1p-53; }

std::vector<double> evenly(double first, double last, int64_t count) {
    std::vector<double> values(count);
    for (int64_t i = 0; i < count; ++i)
        values[i] = count == 1 ? first : first + (last - first) * i / (count - 1);
    return values;
}

}  // namespace

nlohmann::json ScanSensor::to_json() const {
    nlohmann::json j = {{"name", name},
                        {"kind", kind},
                        {"azimuth_step_deg", azimuth_step_deg},
                        {"height", height},
                        {"min_range", min_range},
                        {"max_range", max_range},
                        {"range_sigma", range_sigma},
                        {"dropout", dropout}};
    if (kind == "aerial") {
        j["scan_half_angle_deg"] = scan_half_angle_deg;
        j["line_spacing"] = line_spacing;
        j["track_length"] = track_length;
    } else if (kind == "spinning") {
        j["beams"] = beam_elevations_deg.size();
        j["elevation_max_deg"] =
            *std::max_element(beam_elevations_deg.begin(), beam_elevations_deg.end());
        j["elevation_min_deg"] =
            *std::min_element(beam_elevations_deg.begin(), beam_elevations_deg.end());
    } else {
        j["elevation_min_deg"] = elevation_min_deg;
        j["elevation_step_deg"] = elevation_step_deg;
    }
    return j;
}

const std::vector<std::string>& scan_sensor_names() {
    static const std::vector<std::string> names = {"lidar16", "lidar32", "lidar64", "terrestrial",
                                                   "aerial"};
    return names;
}

ScanSensor scan_sensor(const std::string& name) {
    ScanSensor s;
    s.name = name;
    if (name == "lidar16") {
        s.beam_elevations_deg = evenly(-15, 15, 16);
    } else if (name == "lidar32") {
        s.beam_elevations_deg = evenly(-30.67, 10.67, 32);
    } else if (name == "lidar64") {
        s.beam_elevations_deg = evenly(-24.9, -8.83, 32);
        std::vector<double> upper = evenly(-8.33, 2.0, 32);
        s.beam_elevations_deg.insert(s.beam_elevations_deg.end(), upper.begin(), upper.end());
    } else if (name == "terrestrial") {
        s.kind = "terrestrial";
        s.elevation_min_deg = -60;
        s.elevation_step_deg = 0.4;
        s.azimuth_step_deg = 0.4;
        s.height = 1.5;
        s.min_range = 0.5;
        s.max_range = 100;
        s.range_sigma = 0.005;
        s.dropout = 0.01;
    } else if (name == "aerial") {
        s.kind = "aerial";
        s.height = 400;
        s.scan_half_angle_deg = 5;
        s.azimuth_step_deg = 0.08;
        s.line_spacing = 0.5;
        s.track_length = 70;
        s.min_range = 1;
        s.max_range = 1000;
        s.range_sigma = 0.05;
        s.dropout = 0.02;
    } else {
        throw_input_error("scan sensor",
                          "unknown sensor '{}' (lidar16, lidar32, lidar64, "
                          "terrestrial, aerial)",
                          name);
    }
    return s;
}

namespace {

/// The aerial fan's across-track angles (radians) and the number of lines.
std::pair<std::vector<double>, int64_t> aerial_pattern(const ScanSensor& sensor) {
    if (!(sensor.scan_half_angle_deg > 0 && sensor.scan_half_angle_deg < 90) ||
        !(sensor.line_spacing > 0) || !(sensor.track_length >= 0))
        throw_input_error("scan sensor",
                          "an aerial sensor needs 0 < scan_half_angle_deg < 90, line_spacing > "
                          "0 and track_length >= 0");
    const int64_t rays = 1 + static_cast<int64_t>(std::floor(
                                 2 * sensor.scan_half_angle_deg / sensor.azimuth_step_deg + 1e-9));
    std::vector<double> angles(rays);
    for (int64_t i = 0; i < rays; ++i)
        angles[i] = (-sensor.scan_half_angle_deg + i * sensor.azimuth_step_deg) * kDegree;
    const int64_t lines =
        1 + static_cast<int64_t>(std::floor(sensor.track_length / sensor.line_spacing + 1e-9));
    return {angles, lines};
}

}  // namespace

at::Tensor sensor_directions(const ScanSensor& sensor) {
    if (!(sensor.azimuth_step_deg > 0))
        throw_input_error("scan sensor", "azimuth_step_deg must be positive");
    if (sensor.kind == "aerial") {
        auto [angles, lines] = aerial_pattern(sensor);
        const int64_t fan = static_cast<int64_t>(angles.size());
        at::Tensor directions = at::empty({lines * fan, 3}, at::kDouble);
        double* d = directions.data_ptr<double>();
        for (int64_t l = 0; l < lines; ++l)
            for (int64_t i = 0; i < fan; ++i) {
                double* row = d + 3 * (l * fan + i);
                row[0] = 0;
                row[1] = std::sin(angles[i]);
                row[2] = -std::cos(angles[i]);
            }
        return directions;
    }
    std::vector<double> elevations = sensor.beam_elevations_deg;
    if (sensor.kind == "terrestrial") {
        if (!(sensor.elevation_step_deg > 0) || sensor.elevation_min_deg >= 90)
            throw_input_error("scan sensor",
                              "needs elevation_step_deg > 0 and elevation_min_deg < 90");
        elevations.clear();
        for (int64_t i = 0;; ++i) {
            double e = sensor.elevation_min_deg + i * sensor.elevation_step_deg;
            if (e >= 90 - 1e-9) break;
            elevations.push_back(e);
        }
    } else if (sensor.kind != "spinning") {
        throw_input_error("scan sensor", "unknown kind '{}'", sensor.kind);
    }
    std::sort(elevations.begin(), elevations.end());
    const int64_t azimuths = std::llround(360.0 / sensor.azimuth_step_deg);
    const int64_t rows = static_cast<int64_t>(elevations.size());
    at::Tensor directions = at::empty({azimuths * rows, 3}, at::kDouble);
    double* d = directions.data_ptr<double>();
    for (int64_t a = 0; a < azimuths; ++a) {
        const double azimuth = 2 * kPi * a / azimuths;
        for (int64_t e = 0; e < rows; ++e) {
            const double elevation = elevations[e] * kDegree;
            double* row = d + 3 * (a * rows + e);
            row[0] = std::cos(elevation) * std::cos(azimuth);
            row[1] = std::cos(elevation) * std::sin(azimuth);
            row[2] = std::sin(elevation);
        }
    }
    return directions;
}

namespace {

/// sensor_origins for a sweep of `rays` rays (the count of sensor_directions).
at::Tensor ray_origins(const ScanSensor& sensor, const double origin[3], int64_t rays) {
    at::Tensor position = at::tensor({origin[0], origin[1], origin[2]}, at::kDouble).view({1, 3});
    if (sensor.kind != "aerial") return position.expand({rays, 3}).contiguous();
    auto [angles, lines] = aerial_pattern(sensor);
    const int64_t fan = static_cast<int64_t>(angles.size());
    at::Tensor origins = position.repeat({lines * fan, 1});
    double* o = origins.data_ptr<double>();
    for (int64_t l = 0; l < lines; ++l)
        for (int64_t i = 0; i < fan; ++i)
            o[3 * (l * fan + i)] += -0.5 * sensor.track_length + l * sensor.line_spacing;
    return origins;
}

}  // namespace

at::Tensor sensor_origins(const ScanSensor& sensor, const double origin[3]) {
    return ray_origins(sensor, origin, sensor_directions(sensor).size(0));
}

SceneOptions scene_options_for(const ScanSensor& sensor) {
    SceneOptions options;
    if (sensor.kind == "aerial") {
        options.min_distance = 2;
        options.max_distance = 32;
        options.min_size = 2;
        options.max_size = 10;
        options.walls = 6;
        options.wall_min_thickness = 5;
        options.wall_max_thickness = 12;
        options.wall_min_distance = 6;
        options.wall_clearance = 0;
    }
    return options;
}

Scan simulate_scan(const TriangleBvh& scene, const ScanSensor& sensor, const double origin[3],
                   uint64_t seed) {
    at::Tensor directions = sensor_directions(sensor);
    const int64_t rays = directions.size(0);
    at::Tensor origins = ray_origins(sensor, origin, rays);
    at::Tensor hits = scene.first_hits(origins, directions, sensor.max_range);
    const double* t = hits.data_ptr<double>();
    const double* d = directions.data_ptr<double>();
    const double* o = origins.data_ptr<double>();
    const uint64_t dropout_key = derive_seed(seed, "dropout");
    const uint64_t noise_key = derive_seed(seed, "noise");

    Scan scan;
    scan.rays = rays;
    std::vector<float> points;
    std::vector<double> ranges;
    std::vector<int64_t> index;
    for (int64_t i = 0; i < rays; ++i) {
        if (!(t[i] >= sensor.min_range && t[i] <= sensor.max_range)) continue;
        ++scan.in_range;
        const uint64_t ray = static_cast<uint64_t>(i);
        if (unit_uniform(dropout_key ^ mix(ray)) < sensor.dropout) {
            ++scan.dropped;
            continue;
        }
        // Box–Muller from two independent uniforms of this ray.
        const uint64_t key = noise_key ^ mix(2 * ray);
        const double normal = std::sqrt(-2 * std::log(unit_uniform(key))) *
                              std::cos(2 * kPi * unit_uniform(key ^ mix(2 * ray + 1)));
        const double range = t[i] + sensor.range_sigma * normal;
        for (int k = 0; k < 3; ++k)
            points.push_back(static_cast<float>(o[3 * i + k] + range * d[3 * i + k]));
        ranges.push_back(range);
        index.push_back(i);
    }
    const int64_t n = static_cast<int64_t>(ranges.size());
    scan.points = at::tensor(points, at::kFloat).view({n, 3});
    scan.ranges = at::tensor(ranges, at::kDouble);
    scan.ray_index = at::tensor(index, at::kLong);
    return scan;
}

TriangleMesh merge_meshes(const std::vector<TriangleMesh>& meshes) {
    std::vector<at::Tensor> vertices, faces;
    int64_t offset = 0;
    for (const TriangleMesh& mesh : meshes) {
        vertices.push_back(mesh.vertices.to(at::kFloat));
        faces.push_back(mesh.faces.to(at::kLong) + offset);
        offset += mesh.num_vertices();
    }
    if (vertices.empty()) return {at::empty({0, 3}, at::kFloat), at::empty({0, 3}, at::kLong)};
    return {at::cat(vertices), at::cat(faces)};
}

namespace {

/// An axis-aligned box [lo, hi] as 12 triangles.
TriangleMesh box_mesh(const double lo[3], const double hi[3]) {
    std::vector<float> v;
    for (int i = 0; i < 8; ++i)
        for (int k = 0; k < 3; ++k) v.push_back(static_cast<float>((i >> k) & 1 ? hi[k] : lo[k]));
    // Corner i has x = bit 0, y = bit 1, z = bit 2.
    std::vector<int64_t> f = {0, 2, 3, 0, 3, 1, 4, 5, 7, 4, 7, 6, 0, 1, 5, 0, 5, 4,
                              2, 6, 7, 2, 7, 3, 0, 4, 6, 0, 6, 2, 1, 3, 7, 1, 7, 5};
    return {at::tensor(v, at::kFloat).view({8, 3}), at::tensor(f, at::kLong).view({12, 3})};
}

/// Rotation about z by `yaw` applied to float32 [V,3], then a translation.
at::Tensor yaw_and_move(const at::Tensor& vertices, double yaw, double x, double y, double z) {
    at::Tensor r = at::tensor({std::cos(yaw), -std::sin(yaw), 0.0, std::sin(yaw), std::cos(yaw),
                               0.0, 0.0, 0.0, 1.0},
                              at::kDouble)
                       .view({3, 3});
    at::Tensor moved = at::matmul(vertices.to(at::kDouble), r.t()) +
                       at::tensor({x, y, z}, at::kDouble).view({1, 3});
    return moved.to(at::kFloat);
}

struct Segment {
    double ax, ay, bx, by;
};

double point_segment_distance(double px, double py, const Segment& s) {
    const double dx = s.bx - s.ax, dy = s.by - s.ay;
    const double length_sq = dx * dx + dy * dy;
    double t = length_sq > 0 ? ((px - s.ax) * dx + (py - s.ay) * dy) / length_sq : 0;
    t = std::clamp(t, 0.0, 1.0);
    return std::hypot(px - (s.ax + t * dx), py - (s.ay + t * dy));
}

double segment_distance(const Segment& a, const Segment& b) {
    // Disjoint segments are nearest at an endpoint; crossing ones are at distance 0.
    auto side = [](double ox, double oy, double ax, double ay, double bx, double by) {
        return (ax - ox) * (by - oy) - (ay - oy) * (bx - ox);
    };
    const double d1 = side(a.ax, a.ay, a.bx, a.by, b.ax, b.ay);
    const double d2 = side(a.ax, a.ay, a.bx, a.by, b.bx, b.by);
    const double d3 = side(b.ax, b.ay, b.bx, b.by, a.ax, a.ay);
    const double d4 = side(b.ax, b.ay, b.bx, b.by, a.bx, a.by);
    if (d1 * d2 < 0 && d3 * d4 < 0) return 0;
    return std::min({point_segment_distance(a.ax, a.ay, b), point_segment_distance(a.bx, a.by, b),
                     point_segment_distance(b.ax, b.ay, a), point_segment_distance(b.bx, b.by, a)});
}

}  // namespace

ScanScene build_scan_scene(const std::vector<std::pair<std::string, TriangleMesh>>& objects,
                           uint64_t seed, const SceneOptions& options) {
    std::mt19937_64 rng(seed);
    auto uniform = [&](double lo, double hi) {
        return std::uniform_real_distribution<double>(lo, hi)(rng);
    };
    ScanScene scene;
    scene.elements = nlohmann::json::array();
    std::vector<TriangleMesh> parts;

    const double g = options.ground_half_size;
    parts.push_back(
        {at::tensor({-g, -g, 0.0, g, -g, 0.0, g, g, 0.0, -g, g, 0.0}, at::kFloat).view({4, 3}),
         at::tensor({0, 1, 2, 0, 2, 3}, at::kLong).view({2, 3})});
    scene.elements.push_back({{"name", "ground"}, {"kind", "ground"}, {"half_size", g}});

    std::vector<Segment> walls;
    std::vector<double> wall_thickness;
    for (int64_t w = 0; w < options.walls; ++w) {
        for (int attempt = 0; attempt < 100; ++attempt) {
            const double length = uniform(4, 20), height = uniform(2.5, 8);
            const double thickness =
                options.wall_max_thickness > options.wall_min_thickness
                    ? uniform(options.wall_min_thickness, options.wall_max_thickness)
                    : options.wall_min_thickness;
            const double near = options.wall_min_distance;
            const double distance =
                uniform(std::min(near, options.max_distance), std::max(near, options.max_distance));
            const double azimuth = uniform(0, 2 * kPi);
            const double yaw = azimuth + kPi / 2 + uniform(-kPi / 6, kPi / 6);
            const double cx = distance * std::cos(azimuth), cy = distance * std::sin(azimuth);
            const double hx = 0.5 * length * std::cos(yaw), hy = 0.5 * length * std::sin(yaw);
            Segment segment{cx - hx, cy - hy, cx + hx, cy + hy};
            if (point_segment_distance(0, 0, segment) < options.wall_clearance) continue;
            bool clear = true;
            for (size_t w2 = 0; w2 < walls.size(); ++w2)
                if (segment_distance(segment, walls[w2]) <
                    std::max(1.0, 0.5 * (thickness + wall_thickness[w2]) + 0.5))
                    clear = false;
            if (!clear) continue;
            walls.push_back(segment);
            wall_thickness.push_back(thickness);
            const double lo[3] = {-0.5 * length, -0.5 * thickness, 0};
            const double hi[3] = {0.5 * length, 0.5 * thickness, height};
            TriangleMesh box = box_mesh(lo, hi);
            box.vertices = yaw_and_move(box.vertices, yaw, cx, cy, 0);
            parts.push_back(box);
            scene.elements.push_back({{"name", "wall"},
                                      {"kind", "wall"},
                                      {"position", {cx, cy, 0.0}},
                                      {"size", {length, thickness, height}},
                                      {"yaw_deg", yaw / kDegree}});
            break;
        }
    }

    struct Footprint {
        double x, y, radius;
    };
    std::vector<Footprint> placed;
    const double log_min = std::log(options.min_distance), log_max = std::log(options.max_distance);
    for (const auto& [name, source] : objects) {
        if (source.num_faces() == 0) throw_input_error(name, "scene object has no faces");
        // y up (catalogue convention) to z up: (x, y, z) -> (x, -z, y).
        at::Tensor v = source.vertices.to(at::kDouble);
        v = at::stack({v.select(1, 0), -v.select(1, 2), v.select(1, 1)}, 1);
        const double yaw = uniform(0, 2 * kPi);
        v = yaw_and_move(v.to(at::kFloat), yaw, 0, 0, 0).to(at::kDouble);
        at::Tensor used = v.index_select(0, std::get<0>(at::_unique(source.faces.flatten())));
        at::Tensor lo = std::get<0>(used.min(0)), hi = std::get<0>(used.max(0));
        const double extent = (hi - lo).max().item<double>();
        if (!(extent > 0)) throw_input_error(name, "scene object has zero extent");
        const double size = uniform(options.min_size, options.max_size);
        const double scale = size / extent;
        at::Tensor centre = (lo + hi) * 0.5;
        const double radius =
            0.5 * scale * std::hypot((hi - lo)[0].item<double>(), (hi - lo)[1].item<double>());
        bool done = false;
        for (int attempt = 0; attempt < 100 && !done; ++attempt) {
            const double distance = std::exp(uniform(log_min, log_max));
            const double azimuth = uniform(0, 2 * kPi);
            const double x = distance * std::cos(azimuth), y = distance * std::sin(azimuth);
            if (distance - radius < 0.5 * options.min_distance) continue;
            bool clear = true;
            for (const Footprint& other : placed)
                if (std::hypot(x - other.x, y - other.y) < radius + other.radius + 0.2)
                    clear = false;
            for (size_t w = 0; w < walls.size(); ++w)
                if (point_segment_distance(x, y, walls[w]) < radius + 0.5 * wall_thickness[w] + 0.2)
                    clear = false;
            if (!clear) continue;
            placed.push_back({x, y, radius});
            at::Tensor offset = at::tensor({x, y, 0.0}, at::kDouble) -
                                scale * at::stack({centre[0], centre[1], lo[2]}).to(at::kDouble);
            TriangleMesh mesh{(v * scale + offset.view({1, 3})).to(at::kFloat), source.faces};
            parts.push_back(mesh);
            scene.elements.push_back({{"name", name},
                                      {"kind", "object"},
                                      {"position", {x, y, 0.0}},
                                      {"size", size},
                                      {"distance", distance},
                                      {"yaw_deg", yaw / kDegree}});
            done = true;
        }
    }
    scene.mesh = merge_meshes(parts);
    return scene;
}

}  // namespace pumeta
