#include "support/test_util.h"

#include <ATen/ATen.h>
#include <sys/wait.h>
#include <unistd.h>

#include <fstream>
#include <random>
#include <sstream>
#include <tuple>

#include "pumeta/data/shapes.h"
#include "pumeta/geometry/io.h"

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

CommandResult run_cli(const std::vector<std::string>& args) {
    TempDir dir;
    std::string command = shell_quote(PUMETA_CLI_PATH);
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

at::Tensor random_points(int64_t n, uint64_t seed) {
    std::mt19937_64 rng(seed);
    std::uniform_real_distribution<float> uniform(-1.f, 1.f);
    at::Tensor points = at::empty({n, 3}, at::kFloat);
    float* p = points.data_ptr<float>();
    for (int64_t i = 0; i < 3 * n; ++i) p[i] = uniform(rng);
    return points;
}

std::string source_dir() { return PUMETA_SOURCE_DIR; }

void make_raw_tree(const fs::path& raw) {
    fs::path catalogue = raw / "furniture" / "Mini";
    std::vector<std::tuple<std::string, std::string, std::string>> entries = {
        {"chair", "Kitchen", ""}, {"table", "Kitchen", ""}, {"lamp", "Lights", ""},
        {"walker", "Characters", "Human, People"}};
    fs::create_directories(catalogue);
    std::ofstream properties(catalogue / "PluginFurnitureCatalog.properties");
    for (size_t i = 0; i < entries.size(); ++i) {
        auto [name, category, tags] = entries[i];
        fs::create_directories(catalogue / "mini" / name);
        write_mesh((catalogue / "mini" / name / (name + ".obj")).string(), generate_shape(100 + i));
        properties << "id#" << i + 1 << "=Mini#" << name << "\nname#" << i + 1 << "=" << name
                   << "\ncategory#" << i + 1 << "=" << category << "\ntags#" << i + 1 << "="
                   << tags << "\nmodel#" << i + 1 << "=/mini/" << name << "/" << name
                   << ".obj\n";
    }
    fs::path meshes = raw / "cgal" / "data" / "meshes";
    fs::create_directories(meshes);
    write_mesh((meshes / "anchor.off").string(), generate_shape(7));
    write_mesh((meshes / "bunny00.off").string(), generate_shape(8));
    fs::create_directories(raw / "cgal" / "data" / "points_3");
    write_point_cloud((raw / "cgal" / "data" / "points_3" / "b9_training.ply").string(),
                      {random_points(2000, 3) * 50.0 + 1000.0});
}

}  // namespace pumeta::test
