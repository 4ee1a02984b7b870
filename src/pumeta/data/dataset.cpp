#include "pumeta/data/dataset.h"

#include <ATen/ATen.h>
#include <ATen/Parallel.h>
#include <spdlog/spdlog.h>

#include <algorithm>
#include <atomic>
#include <filesystem>
#include <fstream>
#include <map>
#include <mutex>
#include <random>
#include <set>
#include <thread>

#include "pumeta/core/error.h"
#include "pumeta/core/hash.h"
#include "pumeta/core/json_fields.h"
#include "pumeta/core/progress.h"
#include "pumeta/core/sha256.h"
#include "pumeta/data/layout.h"
#include "pumeta/data/patch_set.h"
#include "pumeta/data/scan_simulation.h"
#include "pumeta/data/shapes.h"
#include "pumeta/data/sources.h"
#include "pumeta/geometry/io.h"
#include "pumeta/geometry/io/file.h"
#include "pumeta/geometry/noise.h"
#include "pumeta/geometry/normalize.h"
#include "pumeta/geometry/sampling.h"
#include "pumeta/metrics/triangle_bvh.h"

namespace pumeta {

namespace fs = std::filesystem;

namespace {

template <class Self, class Visit>
void visit_fields(Self& c, Visit&& visit) {
    visit("raw_dir", c.raw_dir);
    visit("ratios", c.ratios);
    visit("input_points", c.input_points);
    visit("patch_points", c.patch_points);
    visit("patches_per_mesh", c.patches_per_mesh);
    visit("generated_shapes", c.generated_shapes);
    visit("generator_seed", c.generator_seed);
    visit("test_fraction", c.test_fraction);
    visit("val_fraction", c.val_fraction);
    visit("seed", c.seed);
    visit("case_inputs", c.case_inputs);
    visit("relative_noise", c.relative_noise);
    visit("absolute_noise", c.absolute_noise);
    visit("max_models_per_split", c.max_models_per_split);
    visit("splits", c.splits);
    visit("scan_splits", c.scan_splits);
    visit("scan_scenes", c.scan_scenes);
    visit("scan_objects", c.scan_objects);
    visit("scan_seed", c.scan_seed);
}

template <class Self, class Visit>
void visit_scan_split_fields(Self& c, Visit&& visit) {
    visit("split", c.split);
    visit("sensor", c.sensor);
    visit("meshes", c.meshes);
}

constexpr const char* kScanFields[] = {"scan_splits", "scan_scenes", "scan_objects", "scan_seed"};

}  // namespace

ScanSplitConfig ScanSplitConfig::from_json(const nlohmann::json& j) {
    ScanSplitConfig c;
    read_fields(j, "scan split", [&](auto&& visit) { visit_scan_split_fields(c, visit); });
    scan_sensor(c.sensor);  // InputError for an unknown sensor
    if (c.meshes != "test" && c.meshes != "train")
        throw_input_error("scan split", "'meshes' must be \"test\" or \"train\", found \"{}\"",
                          c.meshes);
    for (const char* taken : {"train", "val", layout::kTestIndist, layout::kTestScans,
                              layout::kTestAerial, layout::kTestHumans})
        if (c.split == taken || c.split.empty() || c.split.find('/') != std::string::npos)
            throw_input_error("scan split", "'split' \"{}\" is empty, has a '/' or is taken",
                              c.split);
    return c;
}

nlohmann::json ScanSplitConfig::to_json() const {
    return write_fields([&](auto&& visit) { visit_scan_split_fields(*this, visit); });
}

DatasetConfig DatasetConfig::from_json(const nlohmann::json& j) {
    DatasetConfig c;
    read_fields(j, "dataset config", [&](auto&& visit) { visit_fields(c, visit); });
    if (c.scan_scenes < 0 || c.scan_objects < 0)
        throw_input_error("dataset config", "scan_scenes and scan_objects must be >= 0");
    std::set<std::string> scan_names;
    for (const ScanSplitConfig& scan : c.scan_splits)
        if (!scan_names.insert(scan.split).second)
            throw_input_error("dataset config", "scan split '{}' is listed twice", scan.split);
    for (int64_t r : c.ratios)
        if (r < 2) throw_input_error("dataset config", "ratio {} must be at least 2", r);
    if (c.case_inputs != "poisson" && c.case_inputs != "gt_subset")
        throw_input_error("dataset config", "case_inputs '{}' is not poisson or gt_subset",
                          c.case_inputs);
    if (c.input_points < c.patch_points)
        throw_input_error("dataset config", "input_points {} < patch_points {}", c.input_points,
                          c.patch_points);
    return c;
}

nlohmann::json DatasetConfig::to_json() const {
    nlohmann::json j = write_fields([&](auto&& visit) { visit_fields(*this, visit); });
    // Without simulated scans the manifest's config reads as before they existed.
    if (scan_splits.empty())
        for (const char* field : kScanFields) j.erase(field);
    if (case_inputs == "poisson") j.erase("case_inputs");  // as before the option existed
    return j;
}

namespace {

/// A model to process: either a file of the raw data or a generated shape.
struct Item {
    SourceModel model;
    std::string split;
    uint64_t generator_seed = 0;  ///< for source "generator"
};

std::string case_name(const std::string& id) {
    std::string name = id;
    std::replace(name.begin(), name.end(), '/', '_');
    return name;
}

std::string noise_tag(double value) { return fmt::format("{:g}", value); }

/// Writes the noisy variants of a case's input into `dir` (input_rel<p>.ply for the relative
/// protocol, input_abs<σ>.ply for the absolute one), each seeded by the case id and its file
/// name; returns the case entry's "noisy_inputs": {"rel<p>": file, "abs<σ>": file, ...}.
nlohmann::json write_noisy_inputs(const fs::path& dir, const at::Tensor& input,
                                  const DatasetConfig& config, const std::string& id) {
    nlohmann::json noisy = nlohmann::json::object();
    for (double p : config.relative_noise) {
        std::string file = "input_rel" + noise_tag(p) + ".ply";
        write_point_cloud((dir / file).string(),
                          {add_relative_noise(input, p, derive_seed(config.seed, id + file))});
        noisy["rel" + noise_tag(p)] = file;
    }
    for (double sigma : config.absolute_noise) {
        std::string file = "input_abs" + noise_tag(sigma) + ".ply";
        write_point_cloud((dir / file).string(),
                          {add_absolute_noise(input, sigma, derive_seed(config.seed, id + file))});
        noisy["abs" + noise_tag(sigma)] = file;
    }
    return noisy;
}

}  // namespace

TriangleMesh normalize_to_unit_sphere(TriangleMesh mesh, const std::string& what) {
    at::Tensor v = mesh.vertices.to(at::kDouble);
    at::Tensor a = v.index_select(0, mesh.faces.select(1, 0));
    at::Tensor b = v.index_select(0, mesh.faces.select(1, 1));
    at::Tensor c = v.index_select(0, mesh.faces.select(1, 2));
    at::Tensor area = at::linalg_cross(b - a, c - a).norm(2, 1) * 0.5;
    at::Tensor keep = area > 0;
    if (!keep.any().item<bool>()) throw_input_error(what, "mesh has no face with positive area");
    mesh.faces = mesh.faces.index({keep});
    area = area.index({keep});
    at::Tensor centroids = ((a + b + c) / 3.0).index({keep});
    at::Tensor center = (centroids * area.unsqueeze(1)).sum(0) / area.sum();
    at::Tensor used = std::get<0>(at::_unique(mesh.faces.flatten()));
    double radius = (v.index_select(0, used) - center).norm(2, 1).max().item<double>();
    mesh.vertices = ((v - center) / radius).to(at::kFloat);
    return mesh;
}

namespace {

TriangleMesh load_item_mesh(const Item& item, const std::string& raw_dir) {
    if (item.model.source == "generator") return generate_shape(item.generator_seed);
    return read_mesh((fs::path(raw_dir) / item.model.path).string());
}

/// Runs work(i) for i in [0, n) on as many workers as the caller's torch thread count
/// (`pumeta --threads N`; all cores by default), collecting failures per item.
template <typename Work>
void for_each_parallel(int64_t n, const std::string& label, Work work) {
    std::atomic<int64_t> next{0}, done{0};
    std::mutex mutex;
    ProgressBar progress(n, label);
    const int threads = std::max(1, at::get_num_threads());
    std::vector<std::thread> workers;
    for (int t = 0; t < threads; ++t)
        workers.emplace_back([&] {
            // One thread per worker: parallelism comes from processing models concurrently.
            at::set_num_threads(1);
            for (int64_t i; (i = next++) < n;) {
                work(i);
                std::lock_guard<std::mutex> lock(mutex);
                progress.update(++done);
            }
        });
    for (auto& w : workers) w.join();
    progress.finish();
}

using CaseLists = std::map<std::string, std::map<int64_t, nlohmann::json>>;  // set -> ratio

/// Simulates the scan splits of config.scan_splits (those in config.splits when it is not
/// empty) and writes their cases, adding them to `cases`. items: every model of the raw data
/// and the generator, whatever config.splits says. Returns the manifest's "scans".
nlohmann::json make_scan_splits(const DatasetConfig& config, const std::vector<Item>& items,
                                const std::string& out_dir, CaseLists& cases) {
    std::vector<const ScanSplitConfig*> scans;
    for (const ScanSplitConfig& scan : config.scan_splits)
        if (config.splits.empty() || std::find(config.splits.begin(), config.splits.end(),
                                               scan.split) != config.splits.end())
            scans.push_back(&scan);
    nlohmann::json result = nlohmann::json::object();
    if (scans.empty() || config.scan_scenes == 0) return result;

    // The meshes each kind of scene may use, by id (independent of listing order).
    std::map<std::string, std::vector<const Item*>> pools = {{"test", {}}, {"train", {}}};
    for (const Item& item : items) {
        if (item.model.source == "cgal-aerial") continue;  // points, no mesh
        if (item.split == "train")
            pools["train"].push_back(&item);
        else if (item.split == layout::kTestIndist || item.split == layout::kTestScans ||
                 item.split == layout::kTestHumans)
            pools["test"].push_back(&item);
    }
    for (auto& [kind, pool] : pools)
        std::sort(pool.begin(), pool.end(),
                  [](const Item* a, const Item* b) { return a->model.id < b->model.id; });

    struct Job {
        const ScanSplitConfig* scan;
        std::string name, id;
        nlohmann::json record;
        std::string error;
    };
    std::vector<Job> jobs;
    for (const ScanSplitConfig* scan : scans)
        for (int64_t s = 0; s < config.scan_scenes; ++s) {
            std::string name = fmt::format("scene{:02d}", s);
            jobs.push_back({scan, name, scan->split + "/" + name, nullptr, ""});
        }
    std::mutex cases_mutex;
    for_each_parallel(static_cast<int64_t>(jobs.size()), "scans", [&](int64_t j) {
        Job& job = jobs[j];
        const ScanSplitConfig& scan = *job.scan;
        const std::string& id = job.id;
        try {
            const ScanSensor sensor = scan_sensor(scan.sensor);
            const std::vector<const Item*>& pool = pools.at(scan.meshes);
            std::mt19937_64 rng(derive_seed(config.scan_seed, id + "/objects"));
            std::vector<std::pair<std::string, TriangleMesh>> objects;
            for (int64_t o = 0; o < config.scan_objects; ++o) {
                // Test scenes: every second object a shape generated for this scene alone.
                if (pool.empty() || (scan.meshes == "test" && o % 2 == 1)) {
                    ShapeOptions upright;
                    upright.rotate = false;
                    const uint64_t seed =
                        derive_seed(config.scan_seed, id + "/shape/" + std::to_string(o));
                    objects.push_back(
                        {fmt::format("generated/{:016x}", seed), generate_shape(seed, upright)});
                    continue;
                }
                // A mesh of the pool; one that does not load is replaced by another pick.
                for (int attempt = 0; attempt < 10; ++attempt) {
                    const Item& item = *pool[rng() % pool.size()];
                    try {
                        objects.push_back({item.model.id, normalize_to_unit_sphere(
                                                              load_item_mesh(item, config.raw_dir),
                                                              item.model.id)});
                        break;
                    } catch (const std::exception&) {
                    }
                }
            }
            ScanScene scene = build_scan_scene(
                objects, derive_seed(config.scan_seed, id + "/layout"), scene_options_for(sensor));
            const double origin[3] = {0, 0, sensor.height};
            Scan sweep = simulate_scan(TriangleBvh(scene.mesh), sensor, origin,
                                       derive_seed(config.scan_seed, id + "/sweep"));
            const int64_t max_ratio = *std::max_element(config.ratios.begin(), config.ratios.end());
            if (sweep.points.size(0) < max_ratio)
                throw_input_error(id, "only {} returns", sweep.points.size(0));
            // As the real scans: GT = every return, input = a random 1/r subset, in the frame
            // that maps the sweep to the unit sphere (the scene mesh too, for P2F).
            Normalization frame = unit_sphere_normalization(sweep.points);
            at::Tensor pts = frame.apply(sweep.points);
            fs::path mesh_file = layout::case_mesh_path(out_dir, scan.split, job.name);
            fs::create_directories(mesh_file.parent_path());
            write_mesh(mesh_file.string(), {frame.apply(scene.mesh.vertices), scene.mesh.faces});
            const double metres_per_unit = 1.0 / frame.scale;
            for (int64_t r : config.ratios) {
                const std::string rs = std::to_string(r);
                const int64_t n_in = pts.size(0) / r;
                fs::path dir = layout::cases_dir(out_dir, scan.split, r) / job.name;
                fs::create_directories(dir);
                at::Tensor gt =
                    pts.index_select(0, random_subset(pts.size(0), n_in * r,
                                                      derive_seed(config.seed, id + "/gt/" + rs)));
                at::Tensor input = gt.index_select(
                    0, random_subset(gt.size(0), n_in, derive_seed(config.seed, id + "/in/" + rs)));
                write_point_cloud((dir / layout::kInputFile).string(), {input});
                write_point_cloud((dir / layout::kGtFile).string(), {gt});
                nlohmann::json noisy = write_noisy_inputs(dir, input, config, id);
                nlohmann::json entry = {{"name", job.name},
                                        {"id", id},
                                        {"n_in", n_in},
                                        {"n_gt", gt.size(0)},
                                        {"mesh", layout::case_mesh_entry(job.name)},
                                        {"gt_alt", nullptr},
                                        {"noisy_inputs", noisy},
                                        {"sensor", scan.sensor},
                                        {"metres_per_unit", metres_per_unit}};
                std::lock_guard<std::mutex> lock(cases_mutex);
                cases[scan.split][r].push_back(entry);
            }
            job.record = {{"id", id},
                          {"name", job.name},
                          {"rays", sweep.rays},
                          {"in_range", sweep.in_range},
                          {"dropped", sweep.dropped},
                          {"points", sweep.points.size(0)},
                          {"triangles", scene.mesh.num_faces()},
                          {"metres_per_unit", metres_per_unit},
                          {"elements", scene.elements}};
        } catch (const std::exception& e) {
            std::string message = e.what();
            job.error = message.substr(0, message.find('\n'));
        }
    });
    for (const ScanSplitConfig* scan : scans)
        result[scan->split] = {{"sensor", scan_sensor(scan->sensor).to_json()},
                               {"meshes", scan->meshes},
                               {"scenes", nlohmann::json::array()},
                               {"skipped", nlohmann::json::array()}};
    for (const Job& job : jobs) {
        nlohmann::json& split = result[job.scan->split];
        if (job.error.empty()) {
            split["scenes"].push_back(job.record);
        } else {
            spdlog::warn("dataset: skipping {}: {}", job.id, job.error);
            split["skipped"].push_back({{"id", job.id}, {"reason", job.error}});
        }
    }
    return result;
}

}  // namespace

nlohmann::json make_dataset(const DatasetConfig& config, const std::string& out_dir) {
    fs::create_directories(out_dir);
    std::map<std::string, std::string> raw_sha;  // path -> SHA-256 from get-data's manifest
    std::vector<Item> items;
    if (!config.raw_dir.empty()) {
        std::ifstream manifest(fs::path(config.raw_dir) / "manifest.tsv");
        for (std::string line; std::getline(manifest, line);) {
            std::vector<std::string> cols;
            for (size_t start = 0, tab; start <= line.size(); start = tab + 1) {
                tab = line.find('\t', start);
                if (tab == std::string::npos) tab = line.size();
                cols.push_back(line.substr(start, tab - start));
            }
            if (cols.size() == 4) raw_sha[cols[2]] = cols[3];
        }
        std::vector<SourceModel> models = list_furniture(config.raw_dir);
        std::vector<SourceModel> cgal = list_cgal(config.raw_dir);
        models.insert(models.end(), cgal.begin(), cgal.end());
        std::map<std::string, int64_t> per_split;
        for (const SourceModel& m : models) {
            std::string split = assign_split(m, config.test_fraction, config.val_fraction);
            if (config.max_models_per_split > 0 && per_split[split] >= config.max_models_per_split)
                continue;
            ++per_split[split];
            items.push_back({m, split});
        }
    }
    for (int64_t g = 0; g < config.generated_shapes; ++g) {
        Item item;
        item.generator_seed = derive_seed(config.generator_seed, "shape/" + std::to_string(g));
        item.model.id = fmt::format("generator/{:05d}", g);
        item.model.source = "generator";
        item.model.category = "generated";
        item.model.name = item.model.id;
        item.split = "train";
        items.push_back(item);
    }

    const std::vector<Item> all_items = items;  // what simulated scenes choose from
    if (!config.splits.empty())
        items.erase(std::remove_if(items.begin(), items.end(),
                                   [&](const Item& item) {
                                       return std::find(config.splits.begin(), config.splits.end(),
                                                        item.split) == config.splits.end();
                                   }),
                    items.end());

    // Training and validation clouds per ratio.
    struct Cloud {
        at::Tensor points;  // per ratio
        at::Tensor seeds;
    };
    std::vector<std::map<int64_t, Cloud>> clouds(items.size());
    std::vector<std::string> errors(items.size());
    std::vector<int64_t> order;  // items to process
    for (size_t i = 0; i < items.size(); ++i) order.push_back(static_cast<int64_t>(i));

    std::mutex cases_mutex;
    CaseLists cases;

    for_each_parallel(static_cast<int64_t>(items.size()), "dataset", [&](int64_t i) {
        const Item& item = items[i];
        const std::string& id = item.model.id;
        try {
            if (item.model.source == "cgal-aerial") {
                // Real scan: GT = the real points (normalised), input = a random 1/r subset.
                PointCloud scan = read_point_cloud(
                    (fs::path(config.raw_dir) / item.model.path).string(), {"", true});
                at::Tensor pts = unit_sphere_normalization(scan.points).apply(scan.points);
                for (int64_t r : config.ratios) {
                    int64_t n_in = pts.size(0) / r;
                    std::string name = case_name(id);
                    fs::path dir = layout::cases_dir(out_dir, item.split, r) / name;
                    fs::create_directories(dir);
                    at::Tensor gt = pts.index_select(
                        0,
                        random_subset(pts.size(0), n_in * r,
                                      derive_seed(config.seed, id + "/gt/" + std::to_string(r))));
                    at::Tensor input = gt.index_select(
                        0,
                        random_subset(gt.size(0), n_in,
                                      derive_seed(config.seed, id + "/in/" + std::to_string(r))));
                    write_point_cloud((dir / layout::kInputFile).string(), {input});
                    write_point_cloud((dir / layout::kGtFile).string(), {gt});
                    nlohmann::json entry = {{"name", name},    {"id", id},
                                            {"n_in", n_in},    {"n_gt", gt.size(0)},
                                            {"mesh", nullptr}, {"gt_alt", nullptr}};
                    nlohmann::json noisy = write_noisy_inputs(dir, input, config, id);
                    entry["noisy_inputs"] = noisy;
                    std::lock_guard<std::mutex> lock(cases_mutex);
                    cases[item.split][r].push_back(entry);
                }
                return;
            }
            TriangleMesh mesh = normalize_to_unit_sphere(load_item_mesh(item, config.raw_dir), id);
            if (item.split == "train" || item.split == "val") {
                for (int64_t r : config.ratios) {
                    std::string tag = id + "/train/" + std::to_string(r);
                    PointCloud cloud = sample_poisson_disk(mesh, config.input_points * r,
                                                           derive_seed(config.seed, tag));
                    int64_t start = static_cast<int64_t>(derive_seed(config.seed, tag + "/seed") %
                                                         static_cast<uint64_t>(cloud.size()));
                    int64_t count = std::min(config.patches_per_mesh, cloud.size());
                    clouds[i][r] = {cloud.points,
                                    farthest_point_sampling(cloud.points, count, start)};
                }
                // Validation objects also get test-style cases (cases/val/): object-level
                // tuning (e.g. of test-time adaptation) without touching a test set.
                if (item.split == "train") return;
            }
            // A test (or validation) object with a mesh.
            std::string name = case_name(id);
            fs::path mesh_file = layout::case_mesh_path(out_dir, item.split, name);
            fs::create_directories(mesh_file.parent_path());
            write_mesh(mesh_file.string(), mesh);
            const bool subset = config.case_inputs == "gt_subset";
            const at::Tensor poisson =
                subset ? at::Tensor()
                       : sample_poisson_disk(mesh, config.input_points,
                                             derive_seed(config.seed, id + "/input"))
                             .points;
            for (int64_t r : config.ratios) {
                fs::path dir = layout::cases_dir(out_dir, item.split, r) / name;
                fs::create_directories(dir);
                std::string rs = std::to_string(r);
                PointCloud gt = sample_poisson_disk(mesh, config.input_points * r,
                                                    derive_seed(config.seed, id + "/gt/" + rs));
                PointCloud gt_alt = sample_poisson_disk(
                    mesh, config.input_points * r, derive_seed(config.seed, id + "/gt_alt/" + rs));
                const at::Tensor input =
                    subset ? gt.points.index_select(
                                 0, random_subset(gt.size(), gt.size() / r,
                                                  derive_seed(config.seed, id + "/in/" + rs)))
                           : poisson;
                write_point_cloud((dir / layout::kInputFile).string(), {input});
                write_point_cloud((dir / layout::kGtFile).string(), {gt.points});
                write_point_cloud((dir / layout::kGtAltFile).string(), {gt_alt.points});
                nlohmann::json noisy = write_noisy_inputs(dir, input, config, id);
                nlohmann::json entry = {{"name", name},
                                        {"id", id},
                                        {"n_in", input.size(0)},
                                        {"n_gt", gt.size()},
                                        {"mesh", layout::case_mesh_entry(name)},
                                        {"gt_alt", layout::kGtAltFile},
                                        {"noisy_inputs", noisy}};
                std::lock_guard<std::mutex> lock(cases_mutex);
                cases[item.split][r].push_back(entry);
            }
        } catch (const std::exception& e) {
            std::string message = e.what();
            errors[i] = message.substr(0, message.find('\n'));
        }
    });

    nlohmann::json scans = make_scan_splits(config, all_items, out_dir, cases);

    nlohmann::json manifest;
    manifest["config"] = config.to_json();
    manifest["skipped"] = nlohmann::json::array();
    nlohmann::json splits = nlohmann::json::object();
    for (size_t i = 0; i < items.size(); ++i) {
        const Item& item = items[i];
        if (!errors[i].empty()) {
            spdlog::warn("dataset: skipping {}: {}", item.model.id, errors[i]);
            manifest["skipped"].push_back({{"id", item.model.id}, {"reason", errors[i]}});
            continue;
        }
        nlohmann::json entry = {{"id", item.model.id},
                                {"source", item.model.source},
                                {"category", item.model.category},
                                {"name", item.model.name},
                                {"human", item.model.human}};
        if (item.model.source == "generator") {
            entry["generator_seed"] = item.generator_seed;
        } else {
            entry["path"] = item.model.path;
            auto sha = raw_sha.find(item.model.path);
            entry["sha256"] =
                sha != raw_sha.end()
                    ? sha->second
                    : sha256_file((fs::path(config.raw_dir) / item.model.path).string());
        }
        splits[item.split].push_back(entry);
    }
    manifest["splits"] = splits;
    if (!scans.empty()) manifest["scans"] = scans;
    check_split_integrity(manifest);

    nlohmann::json counts = nlohmann::json::object();
    for (const char* split : {"train", "val"}) {
        for (int64_t r : config.ratios) {
            PatchSet set;
            set.ratio = r;
            set.patch_points = config.patch_points;
            std::vector<at::Tensor> points, seeds;
            std::vector<int64_t> offsets = {0};
            for (size_t i = 0; i < items.size(); ++i) {
                if (items[i].split != split || !errors[i].empty()) continue;
                const Cloud& cloud = clouds[i].at(r);
                int64_t mesh = static_cast<int64_t>(set.ids.size());
                set.ids.push_back(items[i].model.id);
                points.push_back(cloud.points);
                offsets.push_back(offsets.back() + cloud.points.size(0));
                seeds.push_back(at::stack({at::full_like(cloud.seeds, mesh), cloud.seeds}, 1));
            }
            if (points.empty()) continue;
            set.points = at::cat(points);
            set.offsets = at::tensor(offsets, at::kLong);
            set.seeds = at::cat(seeds);
            std::string file = layout::patch_set_file(split, r);
            save_patch_set((fs::path(out_dir) / file).string(), set);
            counts[split][layout::ratio_tag(r)] = {{"file", file},
                                                   {"meshes", set.num_meshes()},
                                                   {"patches", set.num_patches()},
                                                   {"points", set.points.size(0)}};
        }
    }
    for (auto& [set, per_ratio] : cases) {
        for (auto& [r, list] : per_ratio) {
            std::sort(list.begin(), list.end(),
                      [](const nlohmann::json& a, const nlohmann::json& b) {
                          return a["name"] < b["name"];
                      });
            nlohmann::json index = {{"set", set}, {"ratio", r}, {"cases", list}};
            fs::path dir = layout::cases_dir(out_dir, set, r);
            std::ofstream(layout::case_index_path(dir).string()) << index.dump(2) << "\n";
            counts[set][layout::ratio_tag(r)]["cases"] = list.size();
        }
    }
    manifest["counts"] = counts;
    std::string manifest_name = "manifest.json";
    if (!config.splits.empty()) {
        manifest_name = "manifest";
        for (const std::string& split : config.splits) manifest_name += "-" + split;
        for (int64_t r : config.ratios) manifest_name += "-x" + std::to_string(r);
        manifest_name += ".json";
    }
    io::write_atomically((fs::path(out_dir) / manifest_name).string(), manifest.dump(2) + "\n");
    return manifest;
}

void check_split_integrity(const nlohmann::json& manifest) {
    struct Place {
        std::string split, id;
    };
    std::map<std::string, Place> by_id, by_file;
    for (const auto& [split, models] : manifest.at("splits").items()) {
        for (const nlohmann::json& m : models) {
            const std::string id = m.at("id").get<std::string>();
            if (m.at("human").get<bool>() && split != layout::kTestHumans)
                throw InternalError(fmt::format(
                    "dataset: human figure {} in split {} (only test-humans may hold one)", id,
                    split));
            if (auto [it, fresh] = by_id.emplace(id, Place{split, id}); !fresh)
                throw InternalError(
                    fmt::format("dataset: {} is in both {} and {}", id, it->second.split, split));
            if (!m.contains("sha256")) continue;
            const std::string sha = m["sha256"].get<std::string>();
            auto [it, fresh] = by_file.emplace(sha, Place{split, id});
            if (!fresh && it->second.split != split)
                throw InternalError(
                    fmt::format("dataset: {} ({}) and {} ({}) are the same file (SHA-256 {})",
                                it->second.id, it->second.split, id, split, sha.substr(0, 16)));
        }
    }
}

}  // namespace pumeta
