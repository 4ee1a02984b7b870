// Reading speed of the point readers: a 1M-point binary little-endian PLY (x,y,z only, and
// with normals and colours), and a 100k-point ascii XYZ for comparison. Bytes/s counts the
// file's bytes over wall-clock time (the file is in the page cache). The files are generated into a
// fresh directory under /tmp and removed after.
#include "pumeta/geometry/io.h"

#include <ATen/ATen.h>
#include <benchmark/benchmark.h>
#include <unistd.h>

#include <filesystem>
#include <random>

#include "pumeta/geometry/sampling.h"

namespace {

namespace fs = std::filesystem;

/// Uniform points with random normals and colours.
pumeta::PointCloud random_cloud(int64_t n, uint64_t seed) {
    pumeta::PointCloud cloud;
    cloud.points = pumeta::uniform_random_points(n, seed);
    cloud.normals = pumeta::uniform_random_points(n, seed + 1);
    cloud.colors = ((pumeta::uniform_random_points(n, seed + 2) + 1) * 127.5).to(at::kByte);
    return cloud;
}

void read_file_benchmark(benchmark::State& state, const std::string& path) {
    const int64_t bytes = static_cast<int64_t>(fs::file_size(path));
    for (auto _ : state) {
        pumeta::PointCloud cloud = pumeta::read_point_cloud(path);
        benchmark::DoNotOptimize(cloud.points.data_ptr<float>());
    }
    state.SetBytesProcessed(state.iterations() * bytes);
}

}  // namespace

int main(int argc, char** argv) {
    benchmark::Initialize(&argc, argv);
    if (benchmark::ReportUnrecognizedArguments(argc, argv)) return 1;

    const fs::path dir =
        fs::temp_directory_path() / ("pumeta-bench-io-" + std::to_string(getpid()));
    fs::create_directories(dir);
    const pumeta::PointCloud million = random_cloud(1'000'000, 1);
    const std::string ply_xyz = (dir / "xyz_1m.ply").string();
    const std::string ply_full = (dir / "xyz_normals_rgb_1m.ply").string();
    const std::string xyz_text = (dir / "points_100k.xyz").string();
    pumeta::write_point_cloud(ply_xyz, {million.points, {}, {}});
    pumeta::write_point_cloud(ply_full, million);
    pumeta::write_point_cloud(xyz_text, {million.points.slice(0, 0, 100'000), {}, {}});

    benchmark::RegisterBenchmark("ReadPly/binary_le/xyz/1M", read_file_benchmark, ply_xyz)
        ->Unit(benchmark::kMillisecond)
        ->UseRealTime();
    benchmark::RegisterBenchmark("ReadPly/binary_le/xyz+normals+rgb/1M", read_file_benchmark,
                                 ply_full)
        ->Unit(benchmark::kMillisecond)
        ->UseRealTime();
    benchmark::RegisterBenchmark("ReadXyz/ascii/100k", read_file_benchmark, xyz_text)
        ->Unit(benchmark::kMillisecond)
        ->UseRealTime();
    benchmark::RunSpecifiedBenchmarks();
    benchmark::Shutdown();
    fs::remove_all(dir);
    return 0;
}
