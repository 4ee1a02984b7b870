// Open3D 0.16 (Debian libopen3d-dev) reference timings for the foundation benchmarks: the same
// input sizes as bench/geometry (100k random points in [-1,1]³, k = 16; FPS 8192 -> 2048; 100k
// Poisson-disk points on a UV sphere of 49,600 triangles). Built only when Open3D is installed;
// scripts/bench-foundation.sh turns both into ratios.
#include <benchmark/benchmark.h>
#include <omp.h>
#include <open3d/geometry/KDTreeFlann.h>
#include <open3d/geometry/PointCloud.h>
#include <open3d/geometry/TriangleMesh.h>
#include <open3d/utility/Random.h>

#include <cmath>
#include <random>

using namespace open3d;

std::shared_ptr<geometry::PointCloud> random_cloud(int64_t n, uint64_t seed) {
    std::mt19937_64 rng(seed);
    std::uniform_real_distribution<float> uniform(-1.f, 1.f);
    auto pc = std::make_shared<geometry::PointCloud>();
    for (int64_t i = 0; i < n; ++i) {
        float x = uniform(rng), y = uniform(rng), z = uniform(rng);
        pc->points_.emplace_back(x, y, z);
    }
    return pc;
}

std::shared_ptr<geometry::TriangleMesh> uv_sphere(int64_t rings, int64_t sectors) {
    const double pi = std::acos(-1.0);
    auto m = std::make_shared<geometry::TriangleMesh>();
    m->vertices_.emplace_back(0, 0, 1);
    for (int64_t r = 1; r < rings; ++r)
        for (int64_t s = 0; s < sectors; ++s) {
            const double theta = pi * r / rings, phi = 2 * pi * s / sectors;
            m->vertices_.emplace_back(float(std::sin(theta) * std::cos(phi)),
                                      float(std::sin(theta) * std::sin(phi)),
                                      float(std::cos(theta)));
        }
    m->vertices_.emplace_back(0, 0, -1);
    const int south = int(m->vertices_.size()) - 1;
    auto rv = [sectors](int64_t r, int64_t s) { return int(1 + (r - 1) * sectors + s % sectors); };
    for (int64_t s = 0; s < sectors; ++s) {
        m->triangles_.emplace_back(0, rv(1, s), rv(1, s + 1));
        for (int64_t r = 1; r + 1 < rings; ++r) {
            int a = rv(r, s), b = rv(r, s + 1), c = rv(r + 1, s), d = rv(r + 1, s + 1);
            m->triangles_.emplace_back(a, c, d);
            m->triangles_.emplace_back(a, d, b);
        }
        m->triangles_.emplace_back(south, rv(rings - 1, s + 1), rv(rings - 1, s));
    }
    return m;
}

const auto& cloud100k() {
    static auto pc = random_cloud(100000, 1);
    return pc;
}
const auto& sphere() {
    static auto m = uv_sphere(125, 200);
    return m;
}

void query_all(const geometry::KDTreeFlann& tree, const geometry::PointCloud& pc, int threads) {
#pragma omp parallel for num_threads(threads) schedule(static)
    for (int64_t i = 0; i < int64_t(pc.points_.size()); ++i) {
        std::vector<int> idx;
        std::vector<double> d2;
        tree.SearchKNN(pc.points_[i], 16, idx, d2);
        benchmark::DoNotOptimize(idx.data());
    }
}

void BM_O3D_KDTreeBuildAndQuery(benchmark::State& state) {
    for (auto _ : state) {
        geometry::KDTreeFlann tree(*cloud100k());
        query_all(tree, *cloud100k(), state.range(0));
    }
}
BENCHMARK(BM_O3D_KDTreeBuildAndQuery)->Arg(1)->Arg(2)->Unit(benchmark::kMillisecond)->UseRealTime();

void BM_O3D_KDTreeQuery(benchmark::State& state) {
    geometry::KDTreeFlann tree(*cloud100k());
    for (auto _ : state) query_all(tree, *cloud100k(), state.range(0));
}
BENCHMARK(BM_O3D_KDTreeQuery)->Arg(1)->Arg(2)->Unit(benchmark::kMillisecond)->UseRealTime();

void BM_O3D_FarthestPointDownSample(benchmark::State& state) {
    auto pc = random_cloud(8192, 1);
    for (auto _ : state) benchmark::DoNotOptimize(pc->FarthestPointDownSample(2048));
}
BENCHMARK(BM_O3D_FarthestPointDownSample)->Unit(benchmark::kMillisecond)->UseRealTime();

void BM_O3D_SamplePointsUniformly(benchmark::State& state) {
    sphere();
    for (auto _ : state) benchmark::DoNotOptimize(sphere()->SamplePointsUniformly(100000, true));
}
BENCHMARK(BM_O3D_SamplePointsUniformly)->Unit(benchmark::kMillisecond)->UseRealTime();

void BM_O3D_SamplePointsPoissonDisk(benchmark::State& state) {
    sphere();
    for (auto _ : state)
        benchmark::DoNotOptimize(sphere()->SamplePointsPoissonDisk(100000, 5, nullptr, true));
}
BENCHMARK(BM_O3D_SamplePointsPoissonDisk)
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime()
    ->Iterations(1);

BENCHMARK_MAIN();
