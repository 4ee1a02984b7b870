// Data-parallel training across processes and hosts on LibTorch's c10d: rendezvous through a
// TCPStore served by rank 0, collectives through Gloo (CPU tensors) or NCCL (CUDA tensors, in
// builds against a LibTorch that has it). Every collective is called by all ranks in the same
// order; a rank that dies or stops answering makes the others throw within the timeout
// instead of hanging.
//
// Threading: one ProcessGroup per process, used from one thread.
#pragma once

#include <ATen/core/Tensor.h>

#include <cstdint>
#include <functional>
#include <memory>
#include <nlohmann/json.hpp>
#include <string>

#include "pumeta/nn/parameters.h"

namespace pumeta {

/// How a run is spread over processes. world_size 1 (the default) is a plain single-process
/// run: no store, no sockets, and every collective is the identity.
struct DistributedConfig {
    /// W: number of processes (ranks), >= 1.
    int64_t world_size = 1;
    /// This process's rank in [0, W). Rank 0 serves the store and alone writes files.
    int64_t rank = 0;
    /// HOST:PORT of rank 0's TCPStore ("[::1]:29500" for IPv6 literals).
    std::string master = "127.0.0.1:29500";
    /// "gloo" (CPU tensors) or "nccl" (CUDA tensors; only in builds with USE_C10D_NCCL).
    std::string backend = "gloo";
    /// Seconds a rendezvous or collective may wait for the other ranks before failing. Must
    /// exceed the longest time one rank can spend between two collectives (one training step).
    double timeout_seconds = 300;
    /// Verify every this many steps that all ranks hold bit-identical parameters (0: only at
    /// the start). A debugging aid: the all-reduce already makes them identical.
    int64_t check_every = 0;

    bool enabled() const { return world_size > 1; }

    /// Fields not given keep their defaults; InputError for unknown fields or invalid values.
    static DistributedConfig from_json(const nlohmann::json& j);
    nlohmann::json to_json() const;
};

/// Sets the fields of a config's "distributed" object that the environment of a cluster
/// launcher provides: WORLD_SIZE, RANK, MASTER_ADDR and MASTER_PORT (either completes the
/// other half of "master"). Variables that are not set leave `distributed` unchanged.
void apply_distributed_environment(nlohmann::json& distributed);

/// The half-open range [begin, end) of `count` items that `rank` of `world_size` owns:
/// contiguous, disjoint, covering all items, sizes differing by at most one.
struct Shard {
    int64_t begin = 0;
    int64_t end = 0;
    int64_t size() const { return end - begin; }
};
Shard shard_of(int64_t count, int64_t rank, int64_t world_size);

class ProcessGroup {
  public:
    /// Joins the group (blocks until all W ranks have joined, at most the timeout). InputError
    /// for an invalid config; InternalError when the rendezvous fails or times out.
    explicit ProcessGroup(const DistributedConfig& config);
    ~ProcessGroup();
    ProcessGroup(const ProcessGroup&) = delete;
    ProcessGroup& operator=(const ProcessGroup&) = delete;

    int64_t rank() const { return config_.rank; }
    int64_t world_size() const { return config_.world_size; }
    bool is_main() const { return config_.rank == 0; }
    bool enabled() const { return config_.enabled(); }
    const DistributedConfig& config() const { return config_; }

    /// The element-wise sum / mean (floored for integer dtypes) over ranks of every tensor, as new
    /// tensors named like the inputs. Tensors of one dtype and device travel flattened into
    /// one buffer, so a step costs one collective whatever the number of tensors. Every rank
    /// passes the same names and shapes. The inputs are left unchanged (with one rank they
    /// are returned as they are).
    ParamMap sum(const ParamMap& tensors);
    ParamMap average(const ParamMap& tensors);

    /// Overwrites every tensor in place with rank 0's values (one collective per dtype).
    void broadcast(ParamMap& tensors);

    /// Whether every rank holds bit-identical tensors (same names, shapes and bytes). All
    /// ranks get the same answer.
    bool identical(const ParamMap& tensors);

    /// Blocks until every rank has reached it.
    void barrier();

  private:
    struct Backend;
    /// Sum over ranks divided by `divisor`.
    ParamMap reduce(const ParamMap& tensors, int64_t divisor);
    /// Runs one collective, turning c10d's errors into an InternalError that says which
    /// operation failed, on which rank, and why a peer is the likely cause.
    void run(const char* what, const std::function<void(Backend&)>& collective);

    DistributedConfig config_;
    std::unique_ptr<Backend> backend_;
};

/// The start of a data-parallel run, as DDP does at construction: checks that every rank
/// resumes at the same point (`counters`, e.g. {"step": 25, "loader_position": 25}; an
/// InputError naming this rank's values otherwise, typically because a rank could not read
/// rank 0's run directory), then overwrites `state` (parameters, buffers, optimiser moments)
/// in place with rank 0's, so that all ranks start bit-identical.
void start_in_sync(ProcessGroup& group, const nlohmann::json& counters, ParamMap& state);

}  // namespace pumeta
