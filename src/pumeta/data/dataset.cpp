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
#include <thread>

#include "pumeta/core/error.h"
#include "pumeta/core/hash.h"
#include "pumeta/core/json_fields.h"
#include "pumeta/core/progress.h"
#include "pumeta/core/sha256.h"
#include "pumeta/data/layout.h"
#include "pumeta/data/patch_set.h"
#include "pumeta/data/shapes.h"
#include "pumeta/data/sources.h"
#include "pumeta/geometry/io.h"
#include "pumeta/geometry/io/file.h"
#include "pumeta/geometry/noise.h"
#include "pumeta/geometry/normalize.h"
#include "pumeta/geometry/sampling.h"

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
    visit("relative_noise", c.relative_noise);
    visit("absolute_noise", c.absolute_noise);
    visit("max_models_per_split", c.max_models_per_split);
    visit("splits", c.splits);
}

}  // namespace

DatasetConfig DatasetConfig::from_json(const nlohmann::json& j) {
    DatasetConfig c;
    read_fields(j, "dataset config", [&](auto&& visit) { visit_fields(c, visit); });
    for (int64_t r : c.ratios)
        if (r < 2) throw_input_error("dataset config", "ratio {} must be at least 2", r);
    if (c.input_points < c.patch_points)
        throw_input_error("dataset config", "input_points {} < patch_points {}", c.input_points,
                          c.patch_points);
    return c;
}

nlohmann::json DatasetConfig::to_json() const {
    return write_fields([&](auto&& visit) { visit_fields(*this, visit); });
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
    std::map<std::string, std::map<int64_t, nlohmann::json>> cases;  // set -> ratio -> list

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
                    nlohmann::json noisy = nlohmann::json::object();
                    for (double p : config.relative_noise) {
                        std::string file = "input_rel" + noise_tag(p) + ".ply";
                        write_point_cloud(
                            (dir / file).string(),
                            {add_relative_noise(input, p, derive_seed(config.seed, id + file))});
                        noisy["rel" + noise_tag(p)] = file;
                    }
                    for (double s : config.absolute_noise) {
                        std::string file = "input_abs" + noise_tag(s) + ".ply";
                        write_point_cloud(
                            (dir / file).string(),
                            {add_absolute_noise(input, s, derive_seed(config.seed, id + file))});
                        noisy["abs" + noise_tag(s)] = file;
                    }
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
            PointCloud input = sample_poisson_disk(mesh, config.input_points,
                                                   derive_seed(config.seed, id + "/input"));
            for (int64_t r : config.ratios) {
                fs::path dir = layout::cases_dir(out_dir, item.split, r) / name;
                fs::create_directories(dir);
                std::string rs = std::to_string(r);
                PointCloud gt = sample_poisson_disk(mesh, config.input_points * r,
                                                    derive_seed(config.seed, id + "/gt/" + rs));
                PointCloud gt_alt = sample_poisson_disk(
                    mesh, config.input_points * r, derive_seed(config.seed, id + "/gt_alt/" + rs));
                write_point_cloud((dir / layout::kInputFile).string(), {input.points});
                write_point_cloud((dir / layout::kGtFile).string(), {gt.points});
                write_point_cloud((dir / layout::kGtAltFile).string(), {gt_alt.points});
                nlohmann::json noisy = nlohmann::json::object();
                for (double p : config.relative_noise) {
                    std::string file = "input_rel" + noise_tag(p) + ".ply";
                    write_point_cloud(
                        (dir / file).string(),
                        {add_relative_noise(input.points, p, derive_seed(config.seed, id + file))});
                    noisy["rel" + noise_tag(p)] = file;
                }
                for (double s : config.absolute_noise) {
                    std::string file = "input_abs" + noise_tag(s) + ".ply";
                    write_point_cloud(
                        (dir / file).string(),
                        {add_absolute_noise(input.points, s, derive_seed(config.seed, id + file))});
                    noisy["abs" + noise_tag(s)] = file;
                }
                nlohmann::json entry = {{"name", name},
                                        {"id", id},
                                        {"n_in", input.size()},
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
