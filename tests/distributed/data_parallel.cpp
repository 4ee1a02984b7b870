// Distributed meta-training and training through the CLI, run as a cluster runs them: several
// `pumeta` processes meeting on loopback. Two ranks with B/2 tasks each must follow the
// trajectory of one process with B tasks (every step's losses, and the final parameters
// within 1e-5 relative), hold bit-identical parameters after every step (the ranks check it
// themselves with check_every = 1 and fail otherwise), resume from rank 0's run directory
// with any number of processes, and stop with an error when a peer dies or hangs.
#include <ATen/ATen.h>
#include <gtest/gtest.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cmath>
#include <thread>

#include "distributed/free_port.h"
#include "pumeta/data/patch_set.h"
#include "pumeta/geometry/sampling.h"
#include "pumeta/models/backbone.h"
#include "pumeta/models/checkpoint.h"
#include "support/test_util.h"

namespace pumeta {
namespace {

using Clock = std::chrono::steady_clock;

const nlohmann::json kTinyPugcn = {{"backbone", "pugcn"},
                                   {"ratio", 2},
                                   {"channels", 4},
                                   {"k", 4},
                                   {"dilation", 2},
                                   {"upsample_channels", 4},
                                   {"reconstruction_channels", 4},
                                   {"patch_size", 32},
                                   {"downsampler", "random"},
                                   {"seed", 3}};

/// A `pumeta` process, started through run_cli in a forked child that leads its own process
/// group, so that a signal to the group reaches the shell and pumeta alike.
class Process {
  public:
    Process(const std::vector<std::string>& args, const std::string& stderr_file) {
        pid_ = fork();
        if (pid_ == 0) {
            setpgid(0, 0);
            test::CommandResult result = test::run_cli(args);
            test::write_file(stderr_file, result.err);
            _exit(result.exit_code);
        }
        setpgid(pid_, pid_);
    }
    ~Process() {
        if (running_) {
            signal(SIGKILL);
            waitpid(pid_, nullptr, 0);
        }
    }

    void signal(int sig) { kill(-pid_, sig); }

    /// The exit code, or -1 when the process is still running after `timeout` seconds.
    int wait(double timeout) {
        auto deadline = Clock::now() + std::chrono::duration<double>(timeout);
        while (Clock::now() < deadline) {
            int status = 0;
            if (waitpid(pid_, &status, WNOHANG) == pid_) {
                running_ = false;
                return WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
            }
            std::this_thread::sleep_for(std::chrono::milliseconds(20));
        }
        return -1;
    }

  private:
    pid_t pid_ = -1;
    bool running_ = true;
};

class DataParallel : public ::testing::Test {
  protected:
    void SetUp() override {
        // Three "meshes" of random points with eight patch seeds each; GT patches of 64 points
        // (the inner loop's X↓ of 16 points must exceed k·dilation = 8).
        PatchSet set;
        set.ratio = 2;
        set.patch_points = 32;
        set.points = uniform_random_points(600, 21);
        set.offsets = at::tensor({int64_t{0}, int64_t{200}, int64_t{400}, int64_t{600}});
        std::vector<int64_t> seeds;
        for (int64_t mesh = 0; mesh < 3; ++mesh)
            for (int64_t i = 0; i < 8; ++i) seeds.insert(seeds.end(), {mesh, i * 23});
        set.seeds = at::tensor(seeds).view({24, 2});
        set.ids = {"a", "b", "c"};
        save_patch_set(dir_.file("train.tensors"), set);
        save_checkpoint(dir_.file("init.pt"), *make_backbone(kTinyPugcn));
        meta_config_ = {{"init", dir_.file("init.pt")},
                        {"train_data", dir_.file("train.tensors")},
                        {"val_data", dir_.file("train.tensors")},
                        {"val_tasks", 4},
                        {"run_dir", dir_.file("unused")},
                        {"meta", {{"inner_steps", 2}, {"inner_lr", 0.05}}},
                        {"tasks_per_batch", 4},
                        {"steps", 4},
                        {"outer_lr", 1e-2},
                        {"log_every", 1},
                        {"checkpoint_every", 100},
                        {"val_every", 1000},
                        {"seed", 7},
                        {"distributed", {{"timeout_seconds", 60}, {"check_every", 1}}}};
        train_config_ = {{"backbone", kTinyPugcn},
                         {"train_data", dir_.file("train.tensors")},
                         {"run_dir", dir_.file("unused")},
                         {"batch_size", 4},
                         {"steps", 4},
                         {"lr", 1e-2},
                         {"log_every", 1},
                         {"seed", 7},
                         {"distributed", {{"timeout_seconds", 60}, {"check_every", 1}}}};
    }

    std::string write_config(const std::string& name, const nlohmann::json& config) {
        test::write_file(dir_.file(name), config.dump());
        return dir_.file(name);
    }

    /// Arguments of one rank of `world` (no distributed options when world is 1).
    std::vector<std::string> rank_args(const std::string& command, const std::string& config,
                                       const std::string& run_dir, int world, int rank,
                                       const std::string& master,
                                       std::vector<std::string> extra = {}) {
        std::vector<std::string> args = {
            "--threads", "1", command, "--config", config, "--set", "run_dir=" + run_dir};
        if (world > 1)
            args.insert(args.end(), {"--world-size", std::to_string(world), "--rank",
                                     std::to_string(rank), "--master", master});
        args.insert(args.end(), extra.begin(), extra.end());
        return args;
    }

    /// Runs `world` ranks to completion; expects all of them to succeed.
    void run_ranks(const std::string& command, const std::string& config,
                   const std::string& run_dir, int world, std::vector<std::string> extra = {}) {
        std::string master = test::free_master();
        std::vector<std::unique_ptr<Process>> ranks;
        for (int r = 0; r < world; ++r)
            ranks.push_back(std::make_unique<Process>(
                rank_args(command, config, run_dir, world, r, master, extra),
                err_file(run_dir, r)));
        for (int r = 0; r < world; ++r) {
            int code = ranks[r]->wait(240);
            EXPECT_EQ(code, 0) << command << " rank " << r << " of " << world << ": "
                               << test::read_file(err_file(run_dir, r));
        }
    }

    std::string err_file(const std::string& run_dir, int rank) {
        return run_dir + ".rank" + std::to_string(rank) + ".err";
    }

    /// Largest relative difference max|a - b| / max|b| over the parameters of two checkpoints.
    static double max_relative_difference(const std::string& a, const std::string& b) {
        ParamMap pa = load_checkpoint(a).backbone->parameters();
        ParamMap pb = load_checkpoint(b).backbone->parameters();
        double worst = 0;
        for (const auto& [name, tb] : pb) {
            at::Tensor ta = pa.at(name).detach(), ref = tb.detach();
            double scale = std::max(ref.abs().max().item<double>(), 1e-12);
            worst = std::max(worst, (ta - ref).abs().max().item<double>() / scale);
        }
        return worst;
    }

    static void expect_same_losses(const std::vector<nlohmann::json>& got,
                                   const std::vector<nlohmann::json>& want,
                                   const std::vector<std::string>& keys) {
        ASSERT_EQ(got.size(), want.size());
        for (size_t i = 0; i < want.size(); ++i) {
            EXPECT_EQ(got[i]["step"], want[i]["step"]);
            for (const std::string& key : keys) {
                double a = got[i][key], b = want[i][key];
                EXPECT_NEAR(a, b, 1e-5 * std::abs(b)) << key << " at step " << want[i]["step"];
            }
        }
    }

    test::TempDir dir_;
    nlohmann::json meta_config_, train_config_;
};

TEST_F(DataParallel, TwoRanksMetaTrainLikeOneProcessWithTheWholeBatchAndResume) {
    std::string config = write_config("meta.json", meta_config_);
    run_ranks("meta-train", config, dir_.file("one"), 1);
    run_ranks("meta-train", config, dir_.file("two"), 2);
    // Two ranks for two steps, resumed by two ranks for one more and by one for the last.
    run_ranks("meta-train", config, dir_.file("resumed"), 2, {"--set", "steps=2"});
    run_ranks("meta-train", config, dir_.file("resumed"), 2,
              {"--set", "steps=3", "--resume", "--allow-change", "steps"});
    run_ranks("meta-train", config, dir_.file("resumed"), 1,
              {"--set", "steps=4", "--resume", "--allow-change", "steps"});
    if (HasFailure()) return;

    std::vector<nlohmann::json> one =
        test::log_records(dir_.file("one") + "/log.jsonl", "outer_loss");
    ASSERT_EQ(one.size(), 4u);
    const std::vector<std::string> keys = {"outer_loss", "outer_loss_before", "inner_loss_before",
                                           "inner_loss_after"};
    expect_same_losses(test::log_records(dir_.file("two") + "/log.jsonl", "outer_loss"), one, keys);
    expect_same_losses(test::log_records(dir_.file("resumed") + "/log.jsonl", "outer_loss"), one,
                       keys);
    // Validation (steps 0 and 4) is sharded over the ranks and summed: the same scores.
    std::vector<nlohmann::json> validated =
        test::log_records(dir_.file("one") + "/log.jsonl", "val_cd_before");
    ASSERT_EQ(validated.size(), 2u);
    expect_same_losses(test::log_records(dir_.file("two") + "/log.jsonl", "val_cd_before"),
                       validated,
                       {"val_cd_before", "val_cd_after", "val_inner_before", "val_inner_after"});

    std::string reference = dir_.file("one") + "/model.pt";
    EXPECT_LT(max_relative_difference(dir_.file("two") + "/model.pt", reference), 1e-5);
    EXPECT_LT(max_relative_difference(dir_.file("resumed") + "/model.pt", reference), 1e-5);
    // The comparison means something only if training moved the parameters well beyond it.
    EXPECT_GT(max_relative_difference(dir_.file("init.pt"), reference), 1e-2);
}

TEST_F(DataParallel, TwoRanksTrainLikeOneProcessWithTheWholeBatch) {
    std::string config = write_config("train.json", train_config_);
    // Also with two updates per batch: each update's gradients are averaged over the ranks.
    for (const std::string updates : {"1", "2"}) {
        SCOPED_TRACE("updates_per_batch " + updates);
        const std::vector<std::string> set = {"--set", "updates_per_batch=" + updates};
        const std::string one_dir = dir_.file("one" + updates),
                          two_dir = dir_.file("two" + updates);
        run_ranks("train", config, one_dir, 1, set);
        run_ranks("train", config, two_dir, 2, set);
        if (HasFailure()) return;
        std::vector<nlohmann::json> one = test::log_records(one_dir + "/log.jsonl", "loss");
        ASSERT_EQ(one.size(), 4u);
        expect_same_losses(test::log_records(two_dir + "/log.jsonl", "loss"), one, {"loss"});
        EXPECT_LT(max_relative_difference(two_dir + "/model.pt", one_dir + "/model.pt"), 1e-5);
        EXPECT_GT(max_relative_difference(dir_.file("init.pt"), one_dir + "/model.pt"), 1e-2);
    }
    // The second update is a step of its own, not a repeat of the first's outcome.
    EXPECT_GT(
        max_relative_difference(dir_.file("one2") + "/model.pt", dir_.file("one1") + "/model.pt"),
        1e-3);
}

TEST_F(DataParallel, BatchThatDoesNotSplitEvenlyIsAnInputError) {
    std::string config = write_config("meta.json", meta_config_);
    test::CommandResult r =
        test::run_cli(rank_args("meta-train", config, dir_.file("odd"), 3, 0, test::free_master()));
    EXPECT_EQ(r.exit_code, 2) << r.err;
    EXPECT_NE(r.err.find("does not split evenly over 3 processes"), std::string::npos) << r.err;
}

/// How the rank that was not signalled ended: exit code, stderr, and seconds from the signal
/// to its exit.
struct Survivor {
    int exit_code = -1;
    std::string err;
    double seconds = 0;
};

class PeerFailure : public DataParallel {
  protected:
    /// Starts two ranks of a long meta-training run, waits until rank 0 has logged two steps
    /// and sends `sig` to rank `victim`.
    Survivor run_and_signal(int victim, int sig, double timeout) {
        nlohmann::json config = meta_config_;
        config["steps"] = 1000000;
        config["distributed"]["timeout_seconds"] = timeout;
        std::string path = write_config("long.json", config);
        std::string run_dir = dir_.file("long" + std::to_string(runs_++));
        std::string master = test::free_master();
        Process rank0(rank_args("meta-train", path, run_dir, 2, 0, master), err_file(run_dir, 0));
        Process rank1(rank_args("meta-train", path, run_dir, 2, 1, master), err_file(run_dir, 1));
        auto started = Clock::now();
        while (test::log_records(run_dir + "/log.jsonl", "outer_loss").size() < 2 &&
               Clock::now() - started < std::chrono::minutes(2))
            std::this_thread::sleep_for(std::chrono::milliseconds(50));
        EXPECT_GE(test::log_records(run_dir + "/log.jsonl", "outer_loss").size(), 2u)
            << "training never got going";

        Process& victim_process = victim == 0 ? rank0 : rank1;
        Process& survivor_process = victim == 0 ? rank1 : rank0;
        victim_process.signal(sig);
        auto signalled = Clock::now();
        Survivor s;
        s.exit_code = survivor_process.wait(timeout + 60);
        s.seconds = std::chrono::duration<double>(Clock::now() - signalled).count();
        s.err = test::read_file(err_file(run_dir, 1 - victim));
        return s;
    }

    int runs_ = 0;
};

TEST_F(PeerFailure, KilledRankMakesTheOtherExitWithAnError) {
    for (int victim : {1, 0}) {
        Survivor s = run_and_signal(victim, SIGKILL, 30);
        EXPECT_EQ(s.exit_code, 1) << "victim " << victim << ": " << s.err;
        EXPECT_LT(s.seconds, 30) << "victim " << victim;
        EXPECT_NE(s.err.find("pumeta: internal error: distributed:"), std::string::npos)
            << "victim " << victim << ": " << s.err;
    }
}

TEST_F(PeerFailure, HangingRankMakesTheOtherExitWithinTheTimeout) {
    // A stopped process keeps its sockets open: only the timeout can end the wait.
    const double timeout = 4;
    Survivor s = run_and_signal(1, SIGSTOP, timeout);
    EXPECT_EQ(s.exit_code, 1) << s.err;
    EXPECT_GE(s.seconds, 0.5 * timeout);
    EXPECT_LT(s.seconds, timeout + 15);
    EXPECT_NE(s.err.find("did not answer within 4 s"), std::string::npos) << s.err;
}

}  // namespace
}  // namespace pumeta
