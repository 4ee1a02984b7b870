// The scan simulator on tiny scenes: ranges against known geometry, ray counts in a closed
// box, dropout and noise statistics, determinism, range-dependent spacing, scene layout.
#include "pumeta/data/scan_simulation.h"

#include <ATen/ATen.h>
#include <ATen/Parallel.h>
#include <gtest/gtest.h>

#include <cmath>

#include "pumeta/core/error.h"
#include "pumeta/data/shapes.h"
#include "pumeta/geometry/knn.h"

namespace pumeta {
namespace {

constexpr double kDegree = 3.14159265358979323846 / 180;

/// The cube [-h, h]^3 as 12 triangles.
TriangleMesh cube(double h) {
    std::vector<float> v;
    for (int i = 0; i < 8; ++i)
        for (int k = 0; k < 3; ++k) v.push_back(static_cast<float>((i >> k) & 1 ? h : -h));
    std::vector<int64_t> f = {0, 2, 3, 0, 3, 1, 4, 5, 7, 4, 7, 6, 0, 1, 5, 0, 5, 4,
                              2, 6, 7, 2, 7, 3, 0, 4, 6, 0, 6, 2, 1, 3, 7, 1, 7, 5};
    return {at::tensor(v, at::kFloat).view({8, 3}), at::tensor(f, at::kLong).view({12, 3})};
}

ScanSensor exact(ScanSensor sensor) {
    sensor.range_sigma = 0;
    sensor.dropout = 0;
    return sensor;
}

TEST(ScanSensor, PresetsHaveTheirBeamsAndStepsAndUnknownNamesAreRejected) {
    EXPECT_EQ(scan_sensor("lidar16").beam_elevations_deg.size(), 16u);
    EXPECT_EQ(scan_sensor("lidar32").beam_elevations_deg.size(), 32u);
    EXPECT_EQ(scan_sensor("lidar64").beam_elevations_deg.size(), 64u);
    EXPECT_EQ(sensor_directions(scan_sensor("lidar16")).size(0), 16 * 1800);
    EXPECT_EQ(sensor_directions(scan_sensor("lidar64")).size(0), 64 * 1800);
    // Rows -60, -59.6, ..., 89.6: 375 rows of 900 samples.
    EXPECT_EQ(sensor_directions(scan_sensor("terrestrial")).size(0), 375 * 900);
    at::Tensor d = sensor_directions(scan_sensor("lidar32"));
    EXPECT_NEAR(d.norm(2, 1).max().item<double>(), 1.0, 1e-12);
    EXPECT_NEAR(std::asin(d.select(1, 2).max().item<double>()) / kDegree, 10.67, 1e-9);
    EXPECT_NEAR(std::asin(d.select(1, 2).min().item<double>()) / kDegree, -30.67, 1e-9);
    EXPECT_THROW(scan_sensor("lidar128"), InputError);
}

TEST(ScanSimulation, OneBeamOnTheGroundReturnsTheKnownRange) {
    SceneOptions options;
    options.walls = 0;
    ScanScene scene = build_scan_scene({}, 1, options);  // the ground alone
    ScanSensor sensor = exact(scan_sensor("lidar16"));
    sensor.beam_elevations_deg = {-30};
    const double origin[3] = {0, 0, 2};
    Scan scan = simulate_scan(TriangleBvh(scene.mesh), sensor, origin, 7);
    ASSERT_EQ(scan.points.size(0), 1800);
    EXPECT_EQ(scan.rays, 1800);
    EXPECT_EQ(scan.in_range, 1800);
    EXPECT_NEAR((scan.ranges - 4.0).abs().max().item<double>(), 0.0, 1e-9);  // 2 / sin 30°
    EXPECT_NEAR(scan.points.select(1, 2).abs().max().item<float>(), 0.0f, 1e-5f);
    at::Tensor horizontal = scan.points.narrow(1, 0, 2).norm(2, 1);
    EXPECT_NEAR((horizontal - 2 * std::sqrt(3.0)).abs().max().item<float>(), 0.0f, 1e-5f);
    // Beyond max_range the beam returns nothing.
    sensor.max_range = 3.9;
    EXPECT_EQ(simulate_scan(TriangleBvh(scene.mesh), sensor, origin, 7).points.size(0), 0);
}

TEST(ScanSimulation, InsideAClosedBoxEveryRayReturnsOnItsWalls) {
    TriangleBvh box(cube(10));
    const double origin[3] = {0, 0, 0};
    for (const char* name : {"lidar16", "lidar64", "terrestrial"}) {
        ScanSensor sensor = exact(scan_sensor(name));
        Scan scan = simulate_scan(box, sensor, origin, 3);
        EXPECT_EQ(scan.points.size(0), sensor_directions(sensor).size(0)) << name;
        EXPECT_EQ(scan.dropped, 0);
        // Every point is on the cube's surface: its largest coordinate is ±10.
        at::Tensor linf = std::get<0>(scan.points.abs().max(1));
        EXPECT_NEAR((linf - 10).abs().max().item<float>(), 0.0f, 1e-4f) << name;
    }
}

TEST(ScanSimulation, DropoutAndNoiseFollowTheirParameters) {
    TriangleBvh box(cube(10));
    const double origin[3] = {0, 0, 0};
    ScanSensor sensor = scan_sensor("lidar64");
    sensor.dropout = 0.1;
    sensor.range_sigma = 0.03;
    Scan scan = simulate_scan(box, sensor, origin, 11);
    const int64_t rays = 64 * 1800;
    EXPECT_EQ(scan.in_range, rays);
    // Binomial: the standard deviation of the fraction is 0.0009.
    EXPECT_NEAR(static_cast<double>(scan.dropped) / rays, 0.1, 0.005);
    EXPECT_EQ(scan.points.size(0), rays - scan.dropped);
    // True range of a unit direction d inside the cube: 10 / max |d_k|.
    at::Tensor d = sensor_directions(sensor).index_select(0, scan.ray_index);
    at::Tensor truth = 10.0 / std::get<0>(d.abs().max(1));
    at::Tensor error = scan.ranges - truth;
    EXPECT_NEAR(error.mean().item<double>(), 0.0, 0.001);  // 4 standard errors
    EXPECT_NEAR(error.std().item<double>(), 0.03, 0.0006);
    // Points lie on their rays at the measured range.
    at::Tensor along = (scan.points.to(at::kDouble) * d).sum(1);
    EXPECT_NEAR((along - scan.ranges).abs().max().item<double>(), 0.0, 1e-5);
}

TEST(ScanSimulation, TheSameSeedGivesTheSameSweepOnAnyThreadCount) {
    TriangleBvh box(cube(5));
    const double origin[3] = {0.5, -1, 0.25};
    ScanSensor sensor = scan_sensor("lidar32");
    const int threads = at::get_num_threads();
    at::set_num_threads(1);
    Scan one = simulate_scan(box, sensor, origin, 5);
    at::set_num_threads(2);
    Scan two = simulate_scan(box, sensor, origin, 5);
    at::set_num_threads(threads);
    EXPECT_TRUE(at::equal(one.points, two.points));
    EXPECT_TRUE(at::equal(one.ray_index, two.ray_index));
    Scan other = simulate_scan(box, sensor, origin, 6);
    EXPECT_FALSE(other.points.sizes() == one.points.sizes() && at::equal(other.points, one.points));
}

TEST(ScanSimulation, FarReturnsAreSparserThanNearOnes) {
    SceneOptions options;
    options.walls = 6;
    std::vector<std::pair<std::string, TriangleMesh>> objects;
    ShapeOptions upright;
    upright.rotate = false;
    for (uint64_t s = 0; s < 6; ++s) objects.push_back({"shape", generate_shape(s, upright)});
    ScanScene scene = build_scan_scene(objects, 3, options);
    ScanSensor sensor = scan_sensor("lidar32");
    const double origin[3] = {0, 0, sensor.height};
    Scan scan = simulate_scan(TriangleBvh(scene.mesh), sensor, origin, 1);
    ASSERT_GT(scan.points.size(0), 10000);
    // Distance to the nearest other return, for returns nearer than 8 m and beyond 25 m.
    KnnResult nn = knn(scan.points, scan.points, 2);
    at::Tensor spacing = nn.sq_distances.select(1, 1).sqrt();
    at::Tensor near = spacing.index({scan.ranges < 8});
    at::Tensor far = spacing.index({scan.ranges > 25});
    ASSERT_GT(near.size(0), 100);
    ASSERT_GT(far.size(0), 100);
    const double near_median = near.median().item<double>();
    const double far_median = far.median().item<double>();
    // Angular sampling: spacing grows about linearly with range.
    EXPECT_GT(far_median, 3 * near_median) << near_median << " vs " << far_median;
}

TEST(ScanSimulation, AnAerialSensorSweepsTheGroundInLinesAlongItsTrack) {
    SceneOptions options;
    options.walls = 0;
    ScanScene scene = build_scan_scene({}, 1, options);  // the ground alone
    ScanSensor sensor = exact(scan_sensor("aerial"));
    EXPECT_EQ(sensor.kind, "aerial");
    // ±5° every 0.08°: 126 rays a fan; 0.5 m lines over 70 m: 141 fans.
    ASSERT_EQ(sensor_directions(sensor).size(0), 126 * 141);
    const double origin[3] = {3, -2, sensor.height};
    at::Tensor origins = sensor_origins(sensor, origin);
    ASSERT_EQ(origins.sizes(), sensor_directions(sensor).sizes());
    EXPECT_DOUBLE_EQ(origins[0][0].item<double>(), 3 - 35.0);
    EXPECT_DOUBLE_EQ(origins[-1][0].item<double>(), 3 + 35.0);
    EXPECT_TRUE(at::all(origins.select(1, 1) == -2).item<bool>());
    EXPECT_TRUE(at::all(origins.select(1, 2) == sensor.height).item<bool>());

    Scan scan = simulate_scan(TriangleBvh(scene.mesh), sensor, origin, 4);
    ASSERT_EQ(scan.points.size(0), 126 * 141);
    EXPECT_NEAR(scan.points.select(1, 2).abs().max().item<float>(), 0.0f, 1e-3f);
    // The swath: x over the track, y within ±400 tan 5° of it; ranges from 400 (nadir) to
    // 400 / cos 5°.
    EXPECT_NEAR(scan.points.select(1, 0).min().item<float>(), -32.0f, 1e-3f);
    EXPECT_NEAR(scan.points.select(1, 0).max().item<float>(), 38.0f, 1e-3f);
    const double half_swath = 400 * std::tan(5 * kDegree);
    EXPECT_NEAR(scan.points.select(1, 1).max().item<float>(), -2 + half_swath, 1e-2);
    EXPECT_NEAR(scan.points.select(1, 1).min().item<float>(), -2 - half_swath, 1e-2);
    EXPECT_NEAR(scan.ranges.min().item<double>(), 400.0, 0.01);
    EXPECT_NEAR(scan.ranges.max().item<double>(), 400 / std::cos(5 * kDegree), 1e-6);
    // Even spacing: about 0.5 m along the track and 0.56 m across it.
    KnnResult nn = knn(scan.points, scan.points, 2);
    const double spacing = nn.sq_distances.select(1, 1).sqrt().median().item<double>();
    EXPECT_NEAR(spacing, 0.5, 0.01);
}

TEST(ScanScene, AnAerialSceneHasBuildingsAndLargerObjectsNearTheTrack) {
    std::vector<std::pair<std::string, TriangleMesh>> objects;
    for (uint64_t s = 0; s < 6; ++s)
        objects.push_back({"shape" + std::to_string(s), generate_shape(s + 40)});
    const SceneOptions options = scene_options_for(scan_sensor("aerial"));
    ScanScene scene = build_scan_scene(objects, 2, options);
    int64_t buildings = 0;
    for (const auto& e : scene.elements) {
        if (e["kind"] == "wall") {
            ++buildings;
            EXPECT_GE(e["size"][1].get<double>(), 5.0);
            EXPECT_LE(e["size"][1].get<double>(), 12.0);
        } else if (e["kind"] == "object") {
            EXPECT_GE(e["size"].get<double>(), 2.0);
            EXPECT_LE(e["size"].get<double>(), 10.0);
            EXPECT_LE(e["distance"].get<double>(), 32.0);
        }
    }
    EXPECT_GE(buildings, 3);
    // A flight over it sees roofs: returns well above the ground.
    ScanSensor sensor = scan_sensor("aerial");
    const double origin[3] = {0, 0, sensor.height};
    Scan scan = simulate_scan(TriangleBvh(scene.mesh), sensor, origin, 1);
    at::Tensor high = scan.points.select(1, 2) > 2.0f;
    EXPECT_GT(high.sum().item<int64_t>(), scan.points.size(0) / 20);
    // The spinning and terrestrial sensors keep the default layout.
    EXPECT_EQ(scene_options_for(scan_sensor("lidar32")).walls, SceneOptions().walls);
    EXPECT_EQ(scene_options_for(scan_sensor("terrestrial")).wall_max_thickness,
              SceneOptions().wall_max_thickness);
}

TEST(ScanScene, ObjectsStandOnTheGroundApartAtTheirSizesAndDistances) {
    std::vector<std::pair<std::string, TriangleMesh>> objects;
    for (uint64_t s = 0; s < 8; ++s)
        objects.push_back({"shape" + std::to_string(s), generate_shape(s + 20)});
    SceneOptions options;
    ScanScene a = build_scan_scene(objects, 9, options);
    ScanScene b = build_scan_scene(objects, 9, options);
    EXPECT_TRUE(at::equal(a.mesh.vertices, b.mesh.vertices));
    EXPECT_EQ(a.elements, b.elements);
    EXPECT_NE(build_scan_scene(objects, 10, options).elements, a.elements);
    int64_t walls = 0, placed = 0;
    for (const auto& e : a.elements) {
        if (e["kind"] == "wall") ++walls;
        if (e["kind"] != "object") continue;
        ++placed;
        EXPECT_GE(e["size"].get<double>(), options.min_size);
        EXPECT_LE(e["size"].get<double>(), options.max_size);
        EXPECT_GE(e["distance"].get<double>(), options.min_distance);
        EXPECT_LE(e["distance"].get<double>(), options.max_distance);
    }
    EXPECT_EQ(walls, options.walls);
    EXPECT_EQ(placed, 8);
    // Nothing below the ground, the ground at z = 0, nothing near the sensor's column.
    EXPECT_GE(a.mesh.vertices.select(1, 2).min().item<float>(), -1e-4f);
    at::Tensor above = a.mesh.vertices.index({a.mesh.vertices.select(1, 2) > 1e-3});
    EXPECT_GT(above.narrow(1, 0, 2).norm(2, 1).min().item<float>(), 0.9f);
    EXPECT_THROW(build_scan_scene({{"empty", {at::zeros({3, 3}), at::empty({0, 3}, at::kLong)}}}, 1,
                                  options),
                 InputError);
}

}  // namespace
}  // namespace pumeta
