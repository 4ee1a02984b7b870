// Simulated range scans (docs/data.md, "Simulated scans"): outdoor scenes built from triangle
// meshes (a ground plane, walls, objects at 2–60 m) swept by a spinning multi-beam LiDAR, a
// single-station terrestrial scanner or an airborne line scanner. First-hit ray casting through a
// TriangleBvh, Gaussian range noise and random dropouts, all seeded: the same scene, sensor and
// seed give the same points on any thread count.
//
// World frame: metres, z up, the ground at z = 0, the sensor above the origin.
#pragma once

#include <ATen/core/Tensor.h>

#include <cstdint>
#include <nlohmann/json.hpp>
#include <string>
#include <utility>
#include <vector>

#include "pumeta/geometry/point_cloud.h"
#include "pumeta/metrics/triangle_bvh.h"

namespace pumeta {

struct ScanSensor {
    std::string name;
    /// "spinning": beams at fixed elevations, the head turning through 360° of azimuth;
    /// "terrestrial": rows of elevation from elevation_min_deg up to (excluding) 90°, each a
    /// full turn of azimuth; "aerial": a line scanner looking down from an aircraft flying along
    /// +x at `height`, one fan of rays across the track (in the y–z plane, from
    /// −scan_half_angle_deg to +scan_half_angle_deg every azimuth_step_deg) every line_spacing
    /// metres over track_length metres centred on the origin.
    std::string kind = "spinning";
    /// Spinning: the beams' elevation angles in degrees (positive = up).
    std::vector<double> beam_elevations_deg;
    /// Terrestrial: the lowest row and the step between rows, in degrees.
    double elevation_min_deg = -60;
    double elevation_step_deg = 0.2;
    /// The angle between consecutive firings of a beam (spinning), samples of a row
    /// (terrestrial) or rays of a fan (aerial).
    double azimuth_step_deg = 0.2;
    /// Aerial: the fan's half opening angle, the distance between scan lines and the length of
    /// the flight line, metres.
    double scan_half_angle_deg = 5;
    double line_spacing = 0.5;
    double track_length = 70;
    /// Height of the optical centre above the ground, metres.
    double height = 1.8;
    /// Returns nearer than min_range or farther than max_range (true range) are lost.
    double min_range = 1.0;
    double max_range = 100.0;
    /// Standard deviation of the Gaussian range noise, metres.
    double range_sigma = 0.025;
    /// Probability that a return within range is lost anyway.
    double dropout = 0.07;

    nlohmann::json to_json() const;
};

/// The sensors of the simulated splits: "lidar16" (VLP-16-like: 16 beams, +15° to −15° every
/// 2°), "lidar32" (HDL-32-like: 32 beams, +10.67° to −30.67° every 1.33°), "lidar64"
/// (HDL-64-like: 64 beams, +2° to −24.9° in two blocks: 32 beams to −8.33° every 1/3°, 32 to
/// −24.9° every 0.52°), each turning in 0.2° steps, 1.8 m up, 100 m range, σ = 2.5 cm, 7 %
/// dropout; "terrestrial" (a tripod scanner 1.5 m up: rows from −60° to 90° every 0.4°, 0.4°
/// azimuth steps, 0.5–100 m, σ = 5 mm, 1 % dropout); "aerial" (a line scanner 400 m up, a fan of
/// ±5° every 0.08° — about 0.56 m between returns across the track — every 0.5 m along 70 m,
/// up to 1,000 m range, σ = 5 cm, 2 % dropout). InputError for another name.
ScanSensor scan_sensor(const std::string& name);

/// The names scan_sensor knows.
const std::vector<std::string>& scan_sensor_names();

/// The unit ray directions of one sweep, float64 [R,3] in the world frame, firing order
/// (azimuth-major; within one azimuth, beams or rows bottom to top; aerial: line-major, each
/// fan from −y to +y).
at::Tensor sensor_directions(const ScanSensor& sensor);

/// The ray origins of one sweep from the sensor's position `origin`, float64 [R,3] in the order
/// of sensor_directions: `origin` for every ray of a spinning or terrestrial sensor; for an
/// aerial one, the aircraft's position on its track when it fired the ray's line.
at::Tensor sensor_origins(const ScanSensor& sensor, const double origin[3]);

struct Scan {
    at::Tensor points;     ///< float32 [N,3]: origin + measured range · direction, metres
    at::Tensor ranges;     ///< float64 [N]: measured (noisy) ranges
    at::Tensor ray_index;  ///< int64 [N]: the ray of each point in sensor_directions order
    int64_t rays = 0;      ///< rays fired
    int64_t in_range = 0;  ///< rays whose first hit lies within [min_range, max_range]
    int64_t dropped = 0;   ///< of those, lost to dropout
};

/// One sweep of `sensor` from `origin` (world frame; aerial: the track's centre) against the scene.
/// Each ray draws its dropout and noise from (seed, ray index) alone, so the result does not depend
/// on threads.
Scan simulate_scan(const TriangleBvh& scene, const ScanSensor& sensor, const double origin[3],
                   uint64_t seed);

struct SceneOptions {
    /// Objects are placed with their footprint centre at a log-uniform distance in
    /// [min_distance, max_distance] and a uniform azimuth, yawed at random, scaled so that
    /// their largest extent is uniform in [min_size, max_size], standing on the ground, their
    /// footprints disjoint from each other and from the walls. An object that finds no free
    /// place in 100 tries is left out.
    double min_distance = 2;
    double max_distance = 60;
    double min_size = 0.5;
    double max_size = 3;
    /// Walls: boxes 4–20 m long, 2.5–8 m high, their thickness uniform in
    /// [wall_min_thickness, wall_max_thickness] (thick "walls" are building blocks), centred
    /// wall_min_distance to max_distance away, roughly facing the sensor (±30°), their centre
    /// lines at least wall_clearance from the origin and max(1, half their thicknesses + 0.5)
    /// metres from each other.
    int64_t walls = 4;
    double wall_min_thickness = 0.3;
    double wall_max_thickness = 0.3;
    double wall_min_distance = 10;
    double wall_clearance = 5;
    /// The ground: the square [−h, h]² at z = 0.
    double ground_half_size = 150;
};

/// The layout for a sensor's scenes: the defaults above for spinning and terrestrial sensors;
/// for an aerial one, what a flight over a built-up block sees — six buildings (4–20 m by
/// 5–12 m, 2.5–8 m high) 6–32 m from the track's centre, anywhere on it, and objects of 2–10 m
/// (trees, cars, sheds) 2–32 m from it.
SceneOptions scene_options_for(const ScanSensor& sensor);

struct ScanScene {
    TriangleMesh mesh;  ///< ground, walls and placed objects, world frame
    nlohmann::json
        elements;  ///< per element: name, kind, position, size (what the manifest records)
};

/// Builds a scene from `objects` (name, mesh; y up as in the catalogues, any scale: each is
/// rescaled) placed by `seed`. InputError for a mesh without faces.
ScanScene build_scan_scene(const std::vector<std::pair<std::string, TriangleMesh>>& objects,
                           uint64_t seed, const SceneOptions& options = {});

/// The meshes as one (vertices concatenated, faces re-indexed).
TriangleMesh merge_meshes(const std::vector<TriangleMesh>& meshes);

}  // namespace pumeta
