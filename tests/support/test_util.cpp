#include "support/test_util.h"

#include <ATen/ATen.h>
#include <sys/wait.h>
#include <unistd.h>

#include <fstream>
#include <random>
#include <sstream>
#include <tuple>

#include "pumeta/data/dataset.h"
#include "pumeta/data/shapes.h"
#include "pumeta/geometry/io.h"
#include "pumeta/geometry/sampling.h"
#include "pumeta/meta/maml.h"
#include "pumeta/models/backbone.h"
#include "pumeta/models/checkpoint.h"

namespace pumeta::test {

namespace fs = std::filesystem;

TempDir::TempDir() {
    std::string pattern = (fs::temp_directory_path() / "pumeta-test-XXXXXX").string();
    std::vector<char> buffer(pattern.begin(), pattern.end());
    buffer.push_back('\0');
    if (!mkdtemp(buffer.data())) throw std::runtime_error("mkdtemp failed");
    path_ = buffer.data();
}

TempDir::~TempDir() {
    std::error_code ignored;
    fs::remove_all(path_, ignored);
}

static std::string shell_quote(const std::string& s) {
    std::string quoted = "'";
    for (char c : s) quoted += c == '\'' ? std::string("'\\''") : std::string(1, c);
    return quoted + "'";
}

std::string cli_path() { return PUMETA_CLI_PATH; }

CommandResult run_cli(const std::vector<std::string>& args) {
    return run_command(PUMETA_CLI_PATH, args);
}

::testing::AssertionResult one_line_error(const CommandResult& r,
                                          const std::vector<std::string>& fragments) {
    if (r.exit_code != 2)
        return ::testing::AssertionFailure() << "exit " << r.exit_code << ": " << r.err;
    std::string err = r.err;
    while (!err.empty() && err.back() == '\n') err.pop_back();
    const size_t newline = err.rfind('\n');
    const std::string last = newline == std::string::npos ? err : err.substr(newline + 1);
    if (last.rfind("pumeta: error: ", 0) != 0)
        return ::testing::AssertionFailure() << "no error line: " << r.err;
    for (const std::string& fragment : fragments)
        if (last.find(fragment) == std::string::npos)
            return ::testing::AssertionFailure() << "'" << last << "' lacks '" << fragment << "'";
    return ::testing::AssertionSuccess();
}

std::vector<std::vector<std::string>> read_csv(const std::string& path) {
    std::vector<std::vector<std::string>> rows;
    std::ifstream in(path);
    for (std::string line; std::getline(in, line);) {
        rows.emplace_back();
        std::stringstream fields(line);
        for (std::string field; std::getline(fields, field, ',');) rows.back().push_back(field);
        if (!line.empty() && line.back() == ',') rows.back().push_back("");
    }
    return rows;
}

std::string built_program(const std::string& name) {
    fs::path program = fs::path(PUMETA_CLI_PATH).parent_path() / name;
    return access(program.c_str(), X_OK) == 0 ? program.string() : "";
}

std::string find_program(const std::string& name) {
    const char* path = std::getenv("PATH");
    std::stringstream dirs(path ? path : "");
    for (std::string dir; std::getline(dirs, dir, ':');) {
        fs::path candidate = fs::path(dir.empty() ? "." : dir) / name;
        if (access(candidate.c_str(), X_OK) == 0) return candidate.string();
    }
    return "";
}

CommandResult run_command(const std::string& program, const std::vector<std::string>& args) {
    TempDir dir;
    std::string command = shell_quote(program);
    for (const auto& arg : args) command += " " + shell_quote(arg);
    command += " >" + shell_quote(dir.file("out")) + " 2>" + shell_quote(dir.file("err"));
    int status = std::system(command.c_str());
    CommandResult result;
    result.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
    result.out = read_file(dir.file("out"));
    result.err = read_file(dir.file("err"));
    return result;
}

void write_file(const std::string& path, const std::string& text) {
    std::ofstream out(path, std::ios::binary);
    out << text;
}

std::string read_file(const std::string& path) {
    std::ifstream in(path, std::ios::binary);
    std::stringstream buffer;
    buffer << in.rdbuf();
    return buffer.str();
}

std::vector<nlohmann::json> log_records(const std::string& log_file, const std::string& key) {
    std::vector<nlohmann::json> records;
    std::ifstream log(log_file);
    // Only complete lines: getline reaching the end without a newline sets eof, and a writer
    // may be in the middle of that last line.
    for (std::string line; std::getline(log, line) && !log.eof();) {
        nlohmann::json record = nlohmann::json::parse(line);
        if (record.contains(key)) records.push_back(std::move(record));
    }
    return records;
}

at::Tensor sheet(int64_t batch, int64_t n, uint64_t seed, at::ScalarType type) {
    at::Generator gen = at::detail::createCPUGenerator(seed);
    at::Tensor uv = at::rand({batch, n, 2}, gen, at::TensorOptions().dtype(type)) * 2 - 1;
    at::Tensor u = uv.select(2, 0), v = uv.select(2, 1);
    return at::stack({u, v, 0.3 * at::sin(2 * u) * at::cos(v)}, -1);
}

std::string source_dir() { return PUMETA_SOURCE_DIR; }

fs::path pugan_benchmark_dir() {
    return fs::path(source_dir()) / ".." / "shared" / "benchmarks" / "pugan-test";
}

bool have_pugan_benchmark() { return fs::is_directory(pugan_benchmark_dir() / "input_2048"); }

fs::path pugan_benchmark_subset(const TempDir& dir, const std::vector<std::string>& meshes) {
    const fs::path data = dir.path() / "pugan";
    for (const std::string folder : {"input_2048", "gt_8192", "original_meshes"}) {
        fs::create_directories(data / folder);
        for (const std::string& name : meshes) {
            const std::string file = name + (folder == "original_meshes" ? ".off" : ".xyz");
            fs::create_symlink(fs::absolute(pugan_benchmark_dir() / folder / file),
                               data / folder / file);
        }
    }
    return data;
}

void make_raw_tree(const fs::path& raw) {
    fs::path catalogue = raw / "furniture" / "Mini";
    std::vector<std::tuple<std::string, std::string, std::string>> entries = {
        {"chair", "Kitchen", ""},
        {"table", "Kitchen", ""},
        {"lamp", "Lights", ""},
        {"walker", "Characters", "Human, People"}};
    fs::create_directories(catalogue);
    std::ofstream properties(catalogue / "PluginFurnitureCatalog.properties");
    for (size_t i = 0; i < entries.size(); ++i) {
        auto [name, category, tags] = entries[i];
        fs::create_directories(catalogue / "mini" / name);
        write_mesh((catalogue / "mini" / name / (name + ".obj")).string(), generate_shape(100 + i));
        properties << "id#" << i + 1 << "=Mini#" << name << "\nname#" << i + 1 << "=" << name
                   << "\ncategory#" << i + 1 << "=" << category << "\ntags#" << i + 1 << "=" << tags
                   << "\nmodel#" << i + 1 << "=/mini/" << name << "/" << name << ".obj\n";
    }
    fs::path meshes = raw / "cgal" / "data" / "meshes";
    fs::create_directories(meshes);
    write_mesh((meshes / "anchor.off").string(), generate_shape(7));
    write_mesh((meshes / "bunny00.off").string(), generate_shape(8));
    fs::create_directories(raw / "cgal" / "data" / "points_3");
    write_point_cloud((raw / "cgal" / "data" / "points_3" / "b9_training.ply").string(),
                      {uniform_random_points(2000, 3) * 50.0 + 1000.0});
}

namespace {

std::unique_ptr<Backbone> tiny_pugcn(uint64_t seed) {
    return make_backbone({{"backbone", "pugcn"},
                          {"ratio", 4},
                          {"channels", 4},
                          {"k", 4},
                          {"upsample_channels", 4},
                          {"reconstruction_channels", 4},
                          {"patch_size", 32},
                          {"seed", seed}});
}

}  // namespace

nlohmann::json tiny_pugcn_config(int64_t ratio, uint64_t seed) {
    nlohmann::json config = small_backbone_config("pugcn");
    config["ratio"] = ratio;
    config["seed"] = seed;
    return config;
}

nlohmann::json tiny_dispu_config(int64_t ratio) {
    nlohmann::json config = small_backbone_config("dispu");
    config["ratio"] = ratio;
    return config;
}

void save_tiny_meta_model(const std::string& path, uint64_t seed) {
    MetaOptions meta;
    meta.inner_steps = 2;
    meta.inner_lr = 0.01;
    save_checkpoint(path, *tiny_pugcn(seed), {{"meta", meta.to_json()}});
}

void save_tiny_model(const std::string& path, uint64_t seed) {
    save_checkpoint(path, *tiny_pugcn(seed));
}

nlohmann::json make_tiny_reproduction(const fs::path& dir) {
    make_raw_tree(dir / "raw");
    DatasetConfig data;
    data.raw_dir = (dir / "raw").string();
    data.ratios = {4, 3};  // 3x: Table VII
    data.input_points = 128;
    data.patch_points = 32;
    data.patches_per_mesh = 2;
    data.generated_shapes = 1;
    data.test_fraction = 0.5;
    data.val_fraction = 0.0;
    data.relative_noise = {1.0};
    data.absolute_noise = {};
    make_dataset(data, (dir / "data").string());
    fs::create_directories(dir / "models");
    save_tiny_model((dir / "models" / "pugcn-x4.pt").string(), 1);
    save_tiny_meta_model((dir / "models" / "pugcn-x4-meta.pt").string(), 2);
    return {{"dataset_dir", (dir / "data").string()},
            {"models_dir", (dir / "models").string()},
            {"backbones", {"pugcn", "dispu"}},
            {"external_baselines",
             {{{"label", "copy"}, {"command", "cp {input} {output}"}},
              {{"label", "absent"}, {"command", "/nonexistent/upsampler {input} {output}"}}}},
            {"main_ratio", 4},
            {"table3_ratios", {4, 16}},
            {"any_ratios", {3}},
            {"sets", {"test-indist", "test-scans"}},
            {"noise", {"rel1"}},
            {"tta_steps", 2},
            {"steps_sweep", {1}},
            {"sweep_backbones", {"pugcn"}},
            {"tta_lr_without_meta", {{"pugcn", 0.02}}},
            {"zero_shot", {{"steps", 3}, {"batch_patches", 2}, {"max_cases", 1}}},
            {"budgets", {{"quick", {{"max_cases", 2}}}, {"full", nlohmann::json::object()}}}};
}

std::unique_ptr<Backbone> small_pugcn(int64_t ratio) {
    return make_backbone({{"backbone", "pugcn"},
                          {"ratio", ratio},
                          {"channels", 8},
                          {"k", 8},
                          {"upsample_channels", 8},
                          {"reconstruction_channels", 8},
                          {"patch_size", 64},
                          {"seed", 1}});
}

at::Tensor sphere_points(int64_t n, uint64_t seed) {
    at::Tensor p = uniform_random_points(n, seed);
    return p / p.norm(2, 1, true);
}

}  // namespace pumeta::test
