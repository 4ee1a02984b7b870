// Data-parallel meta-training: outer steps per second of PU-GCN (paper width, r = 4, B = 8
// tasks of 256 points, N = 5 second-order inner steps) with 1 process and with 2 processes
// on loopback, and the cost of the one all-reduce per step at the parameter counts of the
// three backbones.
//
// BM_MetaTrain/<processes>/<threads per process> forks real processes, each running
// meta_train() with its own ProcessGroup, and reads rank 0's log. It runs first, before this
// process has run any tensor operation, so that the children start with fresh thread pools. The
// rate is taken between the first and the last logged step, leaving out start-up and the first
// step.
//
// BM_AllReduce/<floats> averages one flat float32 buffer between two ranks (two threads of
// this process over loopback TCP; Gloo's ring all-reduce moves about 2·(W−1)/W of the
// buffer in and out of every rank).
#include <ATen/ATen.h>
#include <ATen/Parallel.h>
#include <arpa/inet.h>
#include <benchmark/benchmark.h>
#include <malloc.h>
#include <netinet/in.h>
#include <spdlog/spdlog.h>
#include <sys/socket.h>
#include <sys/wait.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <stdexcept>
#include <thread>

#include "pumeta/data/patch_set.h"
#include "pumeta/distributed/process_group.h"
#include "pumeta/meta/meta_trainer.h"
#include "pumeta/models/backbone.h"
#include "pumeta/models/checkpoint.h"

namespace {

namespace fs = std::filesystem;
using namespace pumeta;

constexpr int64_t kSteps = 4;

int free_port() {
    int fd = socket(AF_INET, SOCK_STREAM, 0);
    sockaddr_in address{};
    address.sin_family = AF_INET;
    address.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    socklen_t length = sizeof address;
    if (fd < 0 || bind(fd, reinterpret_cast<sockaddr*>(&address), sizeof address) != 0 ||
        getsockname(fd, reinterpret_cast<sockaddr*>(&address), &length) != 0)
        throw std::runtime_error("no free port");
    close(fd);
    return ntohs(address.sin_port);
}

/// Runs `body` in a forked child and waits for it; throws when it fails.
template <typename Body>
void in_child(Body body) {
    pid_t pid = fork();
    if (pid == 0) {
        int code = 0;
        try {
            body();
        } catch (const std::exception& e) {
            std::fprintf(stderr, "child: %s\n", e.what());
            code = 1;
        }
        _exit(code);
    }
    int status = 0;
    waitpid(pid, &status, 0);
    if (!WIFEXITED(status) || WEXITSTATUS(status) != 0) throw std::runtime_error("child failed");
}

fs::path g_workspace;  // removed by main()

/// Training data and the initial model, written once by a child: 8 spheres of 4096 random
/// points with 16 patch seeds each, and a freshly initialised paper-width PU-GCN.
const fs::path& workspace() {
    if (g_workspace.empty()) {
        std::string pattern = (fs::temp_directory_path() / "pumeta-bench-XXXXXX").string();
        if (!mkdtemp(pattern.data())) throw std::runtime_error("mkdtemp failed");
        fs::path path = pattern;
        in_child([&] {
            PatchSet set;
            set.ratio = 4;
            set.patch_points = 256;
            at::manual_seed(1);
            at::Tensor points = at::randn({8 * 4096, 3});
            set.points = points / points.norm(2, 1, true);
            set.offsets = at::arange(0, 9 * 4096, 4096, at::kLong);
            set.seeds = at::stack({at::arange(8, at::kLong).repeat_interleave(16),
                                   at::arange(16, at::kLong).repeat(8) * 250},
                                  1);
            for (int m = 0; m < 8; ++m) set.ids.push_back("sphere" + std::to_string(m));
            save_patch_set((path / "train.tensors").string(), set);
            save_checkpoint((path / "init.pt").string(),
                            *make_backbone({{"backbone", "pugcn"}, {"ratio", 4}}));
        });
        g_workspace = path;
    }
    return g_workspace;
}

/// Outer steps per second between the first and last step records of a meta-training log.
double steps_per_second(const fs::path& log) {
    std::ifstream in(log);
    std::vector<nlohmann::json> steps;
    for (std::string line; std::getline(in, line);) steps.push_back(nlohmann::json::parse(line));
    if (steps.size() < 2) throw std::runtime_error("too few logged steps");
    double seconds = double(steps.back()["seconds"]) - double(steps.front()["seconds"]);
    return double(int64_t(steps.back()["step"]) - int64_t(steps.front()["step"])) / seconds;
}

void BM_MetaTrain(benchmark::State& state) {
    int64_t processes = state.range(0), threads = state.range(1);
    const fs::path& dir = workspace();
    for (auto _ : state) {
        fs::path run = dir / ("run-" + std::to_string(processes) + "x" + std::to_string(threads));
        MetaTrainConfig config;
        config.init = (dir / "init.pt").string();
        config.train_data = (dir / "train.tensors").string();
        config.run_dir = run.string();
        config.meta.inner_steps = 5;
        config.meta.inner_lr = 1e-3;
        config.tasks_per_batch = 8;
        config.steps = kSteps;
        config.log_every = 1;
        config.distributed.world_size = processes;
        config.distributed.master = "127.0.0.1:" + std::to_string(free_port());
        std::vector<pid_t> children;
        for (int64_t rank = 0; rank < processes; ++rank) {
            pid_t pid = fork();
            if (pid == 0) {
                spdlog::set_level(spdlog::level::warn);
                at::set_num_threads(static_cast<int>(threads));
                config.distributed.rank = rank;
                try {
                    meta_train(config, /*resume=*/false);
                } catch (const std::exception& e) {
                    std::fprintf(stderr, "rank %ld: %s\n", static_cast<long>(rank), e.what());
                    _exit(1);
                }
                _exit(0);
            }
            children.push_back(pid);
        }
        bool ok = true;
        for (pid_t pid : children) {
            int status = 0;
            waitpid(pid, &status, 0);
            ok = ok && WIFEXITED(status) && WEXITSTATUS(status) == 0;
        }
        if (!ok) {
            state.SkipWithError("a rank failed");
            break;
        }
        double rate = steps_per_second(run / "log.jsonl");
        state.SetIterationTime(1.0 / rate);
        state.counters["outer_steps/s"] = rate;
    }
}
BENCHMARK(BM_MetaTrain)
    ->ArgNames({"processes", "threads"})
    ->Args({1, 1})
    ->Args({1, 2})
    ->Args({2, 1})
    ->Iterations(1)
    ->UseManualTime()
    ->Unit(benchmark::kSecond);

void BM_AllReduce(benchmark::State& state) {
    int64_t floats = state.range(0);
    DistributedConfig config;
    config.world_size = 2;
    config.master = "127.0.0.1:" + std::to_string(free_port());
    // The peer mirrors every collective of the timed loop; a final one with go = 0 ends it.
    std::thread peer([config, floats]() mutable {
        config.rank = 1;
        ProcessGroup group(config);
        ParamMap packet = {{"g", at::ones({floats})}, {"~go", at::ones({})}};
        while (group.average(packet)["~go"].item<float>() == 1.0f) {
        }
    });
    {
        ProcessGroup group(config);
        ParamMap packet = {{"g", at::ones({floats})}, {"~go", at::ones({})}};
        for (auto _ : state) benchmark::DoNotOptimize(group.average(packet));
        group.average({{"g", at::ones({floats})}, {"~go", at::zeros({})}});
    }
    peer.join();
    state.SetBytesProcessed(state.iterations() * floats * 4);
}
// PU-GCN at r = 4 (75,971 parameters), Dis-PU (about 1.05 M), PU-Dense at paper width
// (about 13.2 M).
BENCHMARK(BM_AllReduce)
    ->ArgName("floats")
    ->Arg(75971)
    ->Arg(1050000)
    ->Arg(13200000)
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();

}  // namespace

int main(int argc, char** argv) {
    // As in bench/models/pugcn.cpp: keep freed memory in the heap instead of returning every
    // large per-edge tensor to the kernel.
    mallopt(M_MMAP_MAX, 0);
    mallopt(M_TRIM_THRESHOLD, 1 << 30);
    benchmark::Initialize(&argc, argv);
    if (benchmark::ReportUnrecognizedArguments(argc, argv)) return 1;
    benchmark::RunSpecifiedBenchmarks();
    benchmark::Shutdown();
    std::error_code ignored;
    if (!g_workspace.empty()) fs::remove_all(g_workspace, ignored);
    return 0;
}
