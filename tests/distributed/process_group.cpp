// The c10d wrapper with W ranks as W threads of this process over loopback TCP: collectives
// against hand-computed values, the consistency check, and failures (a silent peer, a dead
// peer, a missing peer) that must become errors within the timeout instead of hangs.
#include "pumeta/distributed/process_group.h"

#include <ATen/ATen.h>
#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <cstdlib>
#include <future>
#include <map>
#include <thread>

#include "distributed/free_port.h"
#include "pumeta/core/error.h"

namespace pumeta {
namespace {

using Clock = std::chrono::steady_clock;

double seconds_since(Clock::time_point start) {
    return std::chrono::duration<double>(Clock::now() - start).count();
}

DistributedConfig config_for(int64_t world, int64_t rank, const std::string& master,
                             double timeout = 30) {
    DistributedConfig c;
    c.world_size = world;
    c.rank = rank;
    c.master = master;
    c.timeout_seconds = timeout;
    return c;
}

/// Runs body(group) for every rank on its own thread; returns each rank's exception message
/// ("" when it returned normally).
template <typename Body>
std::vector<std::string> run_ranks(int64_t world, Body body, double timeout = 30) {
    std::string master = test::free_master();
    std::vector<std::string> errors(world);
    std::vector<std::thread> threads;
    for (int64_t r = 0; r < world; ++r)
        threads.emplace_back([&, r] {
            try {
                ProcessGroup group(config_for(world, r, master, timeout));
                body(group);
            } catch (const std::exception& e) {
                errors[r] = e.what();
            }
        });
    for (auto& t : threads) t.join();
    return errors;
}

TEST(ProcessGroup, SumAndAverageMatchHandComputedValues) {
    const int64_t world = 3;
    std::vector<ParamMap> sums(world), means(world), inputs(world);
    auto errors = run_ranks(world, [&](ProcessGroup& group) {
        int64_t r = group.rank();
        // Two dtypes: each travels as its own flat buffer.
        ParamMap mine = {{"a", at::arange(6, at::kFloat).view({2, 3}) + (r + 1)},
                         {"b", at::scalar_tensor(10.0 * r, at::kDouble)}};
        inputs[r] = {{"a", mine["a"].clone()}, {"b", mine["b"].clone()}};
        sums[r] = group.sum(mine);
        means[r] = group.average(mine);
        EXPECT_TRUE(mine["a"].equal(inputs[r]["a"])) << "inputs must be left unchanged";
    });
    for (int64_t r = 0; r < world; ++r) {
        ASSERT_EQ(errors[r], "") << "rank " << r;
        // Ranks add 1, 2, 3 to arange(6): sum 3·arange + 6, mean arange + 2.
        EXPECT_TRUE(sums[r]["a"].equal(at::arange(6, at::kFloat).view({2, 3}) * 3 + 6));
        EXPECT_TRUE(means[r]["a"].equal(at::arange(6, at::kFloat).view({2, 3}) + 2));
        EXPECT_EQ(sums[r]["b"].item<double>(), 30.0);
        EXPECT_EQ(means[r]["b"].item<double>(), 10.0);
        EXPECT_EQ(means[r]["b"].scalar_type(), at::kDouble);
    }
}

TEST(ProcessGroup, BroadcastOverwritesInPlaceWithRankZerosValues) {
    const int64_t world = 2;
    std::vector<std::string> failures(world);
    auto errors = run_ranks(world, [&](ProcessGroup& group) {
        int64_t r = group.rank();
        ParamMap params = {
            {"w", at::full({4}, 5.0f + r).requires_grad_(true)},  // a leaf, like parameters
            {"count", at::full({2}, 7 * (r + 1), at::kLong)}};
        void* storage = params["w"].data_ptr();
        group.broadcast(params);
        if (params["w"].data_ptr() != storage) failures[r] = "not in place";
        if (!params["w"].detach().equal(at::full({4}, 5.0f))) failures[r] += " w differs";
        if (!params["count"].equal(at::full({2}, 7, at::kLong))) failures[r] += " count differs";
    });
    for (int64_t r = 0; r < world; ++r) {
        EXPECT_EQ(errors[r], "") << "rank " << r;
        EXPECT_EQ(failures[r], "") << "rank " << r;
    }
}

TEST(ProcessGroup, IdenticalDetectsOneDifferingBitOnAnyRank) {
    const int64_t world = 3;
    std::vector<int> same(world, -1), differs(world, -1);
    auto errors = run_ranks(world, [&](ProcessGroup& group) {
        ParamMap params = {{"x", at::linspace(0, 1, 10)}, {"y", at::ones({3})}};
        same[group.rank()] = group.identical(params);
        if (group.rank() == 2) {
            float* x = params["x"].data_ptr<float>();
            x[4] = std::nextafter(x[4], 2.0f);
        }
        differs[group.rank()] = group.identical(params);
    });
    for (int64_t r = 0; r < world; ++r) {
        ASSERT_EQ(errors[r], "") << "rank " << r;
        EXPECT_EQ(same[r], 1) << "rank " << r;
        EXPECT_EQ(differs[r], 0) << "rank " << r << " must learn that rank 2 differs";
    }
}

TEST(ProcessGroup, SingleRankIsTheIdentityWithoutSockets) {
    ProcessGroup group(DistributedConfig{});  // world 1: no store is started
    ParamMap params = {{"x", at::randn({5})}};
    ParamMap averaged = group.average(params);
    EXPECT_EQ(averaged["x"].data_ptr(), params["x"].data_ptr());
    EXPECT_TRUE(group.identical(params));
    group.broadcast(params);
    group.barrier();
    EXPECT_TRUE(group.is_main());
}

TEST(ProcessGroup, StartInSyncRejectsDifferentResumePointsAndCopiesRankZerosState) {
    auto mismatch = run_ranks(2, [](ProcessGroup& group) {
        ParamMap state = {{"w", at::zeros({2})}};
        start_in_sync(group, {{"step", group.rank() == 0 ? 25 : 0}}, state);
    });
    for (const std::string& e : mismatch) EXPECT_NE(e.find("resumes at"), std::string::npos) << e;

    std::vector<float> values(2);
    auto errors = run_ranks(2, [&](ProcessGroup& group) {
        ParamMap state = {{"w", at::full({2}, 1.0f + group.rank())}};
        start_in_sync(group, {{"step", 25}, {"loader_position", 50}}, state);
        values[group.rank()] = state["w"][1].item<float>();
    });
    EXPECT_EQ(errors, std::vector<std::string>(2));
    EXPECT_EQ(values, std::vector<float>({1.0f, 1.0f}));
}

TEST(ProcessGroup, SilentPeerMakesACollectiveFailWithinTheTimeout) {
    const double timeout = 2;
    std::promise<void> rank0_done;
    std::shared_future<void> done = rank0_done.get_future().share();
    double elapsed = 0;
    auto errors = run_ranks(
        2,
        [&](ProcessGroup& group) {
            if (group.rank() == 1) {
                done.wait();  // alive, connected, but never joins the collective
                return;
            }
            auto start = Clock::now();
            try {
                group.average({{"g", at::ones({1000})}});
            } catch (...) {
                elapsed = seconds_since(start);
                rank0_done.set_value();
                throw;
            }
            rank0_done.set_value();
        },
        timeout);
    EXPECT_NE(errors[0].find("all-reduce failed on rank 0 of 2"), std::string::npos) << errors[0];
    EXPECT_GE(elapsed, 0.5 * timeout);
    EXPECT_LT(elapsed, timeout + 10);
    EXPECT_EQ(errors[1], "");
}

TEST(ProcessGroup, DeadPeerMakesACollectiveFailLongBeforeTheTimeout) {
    const double timeout = 60;
    std::promise<void> rank1_gone;
    std::shared_future<void> gone = rank1_gone.get_future().share();
    double elapsed = 0;
    std::string master = test::free_master();
    std::string error0;
    std::thread rank0([&] {
        try {
            ProcessGroup group(config_for(2, 0, master, timeout));
            gone.wait();
            auto start = Clock::now();
            try {
                group.average({{"g", at::ones({1000})}});
            } catch (...) {
                elapsed = seconds_since(start);
                throw;
            }
        } catch (const std::exception& e) {
            error0 = e.what();
        }
    });
    {
        // Rank 1 joins and then disappears: its sockets close, as when a process is killed.
        ProcessGroup group(config_for(2, 1, master, timeout));
    }
    rank1_gone.set_value();
    rank0.join();
    EXPECT_NE(error0.find("all-reduce failed on rank 0 of 2"), std::string::npos) << error0;
    EXPECT_LT(elapsed, 10.0);
}

TEST(ProcessGroup, MissingPeerMakesTheRendezvousFailWithinTheTimeout) {
    // Rank 0 waits for its workers; rank 1 keeps retrying to reach a master that may start
    // late (c10d gives up about a second before the deadline).
    const double timeout = 3;
    for (int64_t rank : {0, 1}) {
        auto start = Clock::now();
        try {
            ProcessGroup group(config_for(2, rank, test::free_master(), timeout));
            ADD_FAILURE() << "rank " << rank << " joined a group whose peer never came";
        } catch (const InternalError& e) {
            EXPECT_NE(std::string(e.what()).find("could not join"), std::string::npos) << e.what();
        }
        double elapsed = seconds_since(start);
        EXPECT_GE(elapsed, timeout - 1.5) << "rank " << rank;
        EXPECT_LT(elapsed, timeout + 10) << "rank " << rank;
    }
}

TEST(Shard, ShardsAreContiguousDisjointCoveringAndBalanced) {
    for (int64_t count = 0; count <= 20; ++count)
        for (int64_t world = 1; world <= 5; ++world) {
            int64_t next = 0, smallest = count, largest = 0;
            for (int64_t r = 0; r < world; ++r) {
                Shard s = shard_of(count, r, world);
                EXPECT_EQ(s.begin, next) << count << " " << world << " " << r;
                next = s.end;
                smallest = std::min(smallest, s.size());
                largest = std::max(largest, s.size());
            }
            EXPECT_EQ(next, count);
            EXPECT_LE(largest - smallest, 1);
        }
}

TEST(DistributedConfig, RejectsInvalidSettings) {
    EXPECT_THROW(DistributedConfig::from_json({{"world_size", 2}, {"rank", 2}}), InputError);
    EXPECT_THROW(DistributedConfig::from_json({{"world_size", 0}}), InputError);
    EXPECT_THROW(DistributedConfig::from_json({{"master", "localhost"}}), InputError);
    EXPECT_THROW(DistributedConfig::from_json({{"master", "localhost:70000"}}), InputError);
    EXPECT_THROW(DistributedConfig::from_json({{"backend", "mpi"}}), InputError);
    EXPECT_THROW(DistributedConfig::from_json({{"ranks", 2}}), InputError);
    DistributedConfig c = DistributedConfig::from_json(
        {{"world_size", 4}, {"rank", 3}, {"master", "[::1]:1234"}, {"timeout_seconds", 5}});
    EXPECT_EQ(DistributedConfig::from_json(c.to_json()).to_json(), c.to_json());
}

/// Sets environment variables for one scope and restores the previous values.
class ScopedEnvironment {
  public:
    using Values = std::map<std::string, std::string>;
    explicit ScopedEnvironment(const Values& values) {
        for (const char* name : {"WORLD_SIZE", "RANK", "MASTER_ADDR", "MASTER_PORT"}) {
            if (const char* old = std::getenv(name)) saved_[name] = old;
            unsetenv(name);
        }
        for (const auto& [name, value] : values) setenv(name.c_str(), value.c_str(), 1);
    }
    ~ScopedEnvironment() {
        for (const char* name : {"WORLD_SIZE", "RANK", "MASTER_ADDR", "MASTER_PORT"})
            unsetenv(name);
        for (const auto& [name, value] : saved_) setenv(name.c_str(), value.c_str(), 1);
    }

  private:
    std::map<std::string, std::string> saved_;
};

TEST(DistributedConfig, EnvironmentOfAClusterLauncherFillsTheConfig) {
    {
        ScopedEnvironment env(ScopedEnvironment::Values{{"WORLD_SIZE", "4"},
                                                        {"RANK", "2"},
                                                        {"MASTER_ADDR", "10.1.2.3"},
                                                        {"MASTER_PORT", "4000"}});
        nlohmann::json j = {{"world_size", 1}, {"timeout_seconds", 9}};
        apply_distributed_environment(j);
        EXPECT_EQ(j, nlohmann::json({{"world_size", 4},
                                     {"rank", 2},
                                     {"master", "10.1.2.3:4000"},
                                     {"timeout_seconds", 9}}));
    }
    {
        ScopedEnvironment env(
            ScopedEnvironment::Values{{"MASTER_PORT", "4000"}});  // the host stays the config's
        nlohmann::json j = {{"master", "node7:29500"}};
        apply_distributed_environment(j);
        EXPECT_EQ(j["master"], "node7:4000");
    }
    {
        ScopedEnvironment env(ScopedEnvironment::Values{{"MASTER_ADDR", "::1"}});
        nlohmann::json j;
        apply_distributed_environment(j);
        EXPECT_EQ(j["master"], "[::1]:29500");
        EXPECT_EQ(DistributedConfig::from_json(j).master, "[::1]:29500");
    }
    {
        ScopedEnvironment env(ScopedEnvironment::Values{});
        nlohmann::json j = {{"rank", 1}};
        apply_distributed_environment(j);
        EXPECT_EQ(j, nlohmann::json({{"rank", 1}}));
    }
    ScopedEnvironment env(ScopedEnvironment::Values{{"WORLD_SIZE", "two"}});
    nlohmann::json j;
    EXPECT_THROW(apply_distributed_environment(j), InputError);
}

}  // namespace
}  // namespace pumeta
