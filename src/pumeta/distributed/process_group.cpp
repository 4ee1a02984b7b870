#include "pumeta/distributed/process_group.h"

#include <ATen/ATen.h>
#include <c10/util/Exception.h>

#include <torch/csrc/distributed/c10d/ProcessGroupGloo.hpp>
#include <torch/csrc/distributed/c10d/TCPStore.hpp>
#ifdef USE_C10D_NCCL
#include <torch/csrc/distributed/c10d/ProcessGroupNCCL.hpp>
#endif

#include <chrono>
#include <cstdlib>
#include <map>
#include <string_view>

#include "pumeta/core/error.h"
#include "pumeta/core/hash.h"
#include "pumeta/core/json_fields.h"

namespace pumeta {

namespace {

struct HostPort {
    std::string host;
    uint16_t port = 0;
};

HostPort parse_master(const std::string& master) {
    size_t colon = master.rfind(':');
    if (colon == std::string::npos || colon == 0 || colon + 1 == master.size())
        throw_input_error("distributed config", "master '{}' is not HOST:PORT", master);
    HostPort result;
    result.host = master.substr(0, colon);
    if (result.host.size() > 2 && result.host.front() == '[' && result.host.back() == ']')
        result.host = result.host.substr(1, result.host.size() - 2);
    std::string port = master.substr(colon + 1);
    char* end = nullptr;
    long value = std::strtol(port.c_str(), &end, 10);
    if (*end != '\0' || value < 1 || value > 65535)
        throw_input_error("distributed config", "master '{}' has an invalid port", master);
    result.port = static_cast<uint16_t>(value);
    return result;
}

bool is_loopback(const std::string& host) {
    return host == "localhost" || host == "::1" || host.rfind("127.", 0) == 0;
}

std::string first_line(const std::exception& e) {
    const auto* c10_error = dynamic_cast<const c10::Error*>(&e);
    std::string message = c10_error ? c10_error->what_without_backtrace() : e.what();
    return message.substr(0, message.find('\n'));
}

/// A hash of names, shapes and raw bytes (copied to the CPU): equal states hash equal, and a
/// difference anywhere changes the hash with overwhelming probability.
uint64_t fingerprint(const ParamMap& tensors) {
    auto bytes = [](const void* data, size_t size) {
        return std::string_view(static_cast<const char*>(data), size);
    };
    std::vector<uint64_t> parts;
    for (const auto& [name, t] : tensors) {
        at::Tensor cpu = t.detach().to(at::kCPU).contiguous();
        parts.push_back(stable_hash(name));
        parts.push_back(stable_hash(bytes(t.sizes().data(), t.sizes().size() * sizeof(int64_t))));
        parts.push_back(stable_hash(bytes(cpu.data_ptr(), cpu.nbytes())));
    }
    return stable_hash(bytes(parts.data(), parts.size() * sizeof(uint64_t)));
}

}  // namespace

namespace {

template <class Self, class Visit>
void visit_fields(Self& c, Visit&& visit) {
    visit("world_size", c.world_size);
    visit("rank", c.rank);
    visit("master", c.master);
    visit("backend", c.backend);
    visit("timeout_seconds", c.timeout_seconds);
    visit("check_every", c.check_every);
}

}  // namespace

DistributedConfig DistributedConfig::from_json(const nlohmann::json& j) {
    DistributedConfig c;
    if (j.is_null()) return c;
    read_fields(j, "distributed config", [&](auto&& visit) { visit_fields(c, visit); });
    if (c.world_size < 1) throw_input_error("distributed config", "world_size must be >= 1");
    if (c.rank < 0 || c.rank >= c.world_size)
        throw_input_error("distributed config", "rank {} is outside [0, {})", c.rank, c.world_size);
    if (c.backend != "gloo" && c.backend != "nccl")
        throw_input_error("distributed config", "backend '{}' (expected gloo or nccl)", c.backend);
    if (!(c.timeout_seconds > 0))
        throw_input_error("distributed config", "timeout_seconds must be positive");
    if (c.check_every < 0) throw_input_error("distributed config", "check_every must be >= 0");
    parse_master(c.master);
    return c;
}

nlohmann::json DistributedConfig::to_json() const {
    return write_fields([&](auto&& visit) { visit_fields(*this, visit); });
}

void apply_distributed_environment(nlohmann::json& distributed) {
    auto integer = [](const char* variable, const char* value) {
        char* end = nullptr;
        long long n = std::strtoll(value, &end, 10);
        if (*value == '\0' || *end != '\0')
            throw_input_error("environment", "{}='{}' is not an integer", variable, value);
        return static_cast<int64_t>(n);
    };
    if (!distributed.is_object()) distributed = nlohmann::json::object();
    if (const char* v = std::getenv("WORLD_SIZE"))
        distributed["world_size"] = integer("WORLD_SIZE", v);
    if (const char* v = std::getenv("RANK")) distributed["rank"] = integer("RANK", v);
    const char* addr = std::getenv("MASTER_ADDR");
    const char* port = std::getenv("MASTER_PORT");
    if (addr || port) {
        HostPort current = parse_master(distributed.value("master", DistributedConfig().master));
        std::string host = addr ? std::string(addr) : current.host;
        if (host.find(':') != std::string::npos) host = "[" + host + "]";  // IPv6 literal
        distributed["master"] =
            host + ":" + (port ? std::string(port) : std::to_string(current.port));
    }
}

Shard shard_of(int64_t count, int64_t rank, int64_t world_size) {
    return {count * rank / world_size, count * (rank + 1) / world_size};
}

struct ProcessGroup::Backend {
    c10::intrusive_ptr<c10d::Store> store;
    c10::intrusive_ptr<c10d::ProcessGroup> group;
    /// Where scratch tensors of collectives live: the CPU for Gloo, the GPU for NCCL.
    at::Device device = at::kCPU;
};

ProcessGroup::ProcessGroup(const DistributedConfig& config)
    : config_(DistributedConfig::from_json(config.to_json())) {
    if (!config_.enabled()) return;
    HostPort master = parse_master(config_.master);
    auto timeout = std::chrono::milliseconds(static_cast<int64_t>(config_.timeout_seconds * 1e3));
    int rank = static_cast<int>(config_.rank), size = static_cast<int>(config_.world_size);
    backend_ = std::make_unique<Backend>();
    try {
        c10d::TCPStoreOptions store_options;
        store_options.port = master.port;
        store_options.isServer = rank == 0;
        store_options.numWorkers = static_cast<size_t>(size);
        store_options.waitWorkers = false;
        store_options.timeout = timeout;
        backend_->store = c10::make_intrusive<c10d::TCPStore>(master.host, store_options);
        if (config_.backend == "gloo") {
            auto options = c10d::ProcessGroupGloo::Options::create(timeout);
            // Loopback rendezvous means a single-host run: bind there. Otherwise the
            // interface named by GLOO_SOCKET_IFNAME, or the one the hostname resolves to.
            if (is_loopback(master.host))
                options->devices.push_back(
                    c10d::ProcessGroupGloo::createDeviceForHostname(master.host));
            else if (const char* interface = std::getenv("GLOO_SOCKET_IFNAME"))
                options->devices.push_back(
                    c10d::ProcessGroupGloo::createDeviceForInterface(interface));
            else
                options->devices.push_back(c10d::ProcessGroupGloo::createDefaultDevice());
            backend_->group =
                c10::make_intrusive<c10d::ProcessGroupGloo>(backend_->store, rank, size, options);
        } else {
#ifdef USE_C10D_NCCL
            // Without blocking waits NCCL ignores the timeout and a dead peer hangs the rest.
            setenv("NCCL_BLOCKING_WAIT", "1", /*overwrite=*/0);
            auto options = c10d::ProcessGroupNCCL::Options::create();
            options->timeout = timeout;
            backend_->group =
                c10::make_intrusive<c10d::ProcessGroupNCCL>(backend_->store, rank, size, options);
            backend_->device = at::Device(at::kCUDA);
#else
            throw_input_error("distributed config",
                              "backend 'nccl' needs a LibTorch built with NCCL (USE_C10D_NCCL)");
#endif
        }
    } catch (const InputError&) {
        throw;
    } catch (const std::exception& e) {
        throw InternalError(
            fmt::format("distributed: rank {} of {} could not join the group at {} within {} s: {}",
                        rank, size, config_.master, config_.timeout_seconds, first_line(e)));
    }
}

ProcessGroup::~ProcessGroup() = default;

void ProcessGroup::run(const char* what, const std::function<void(Backend&)>& collective) {
    try {
        collective(*backend_);
    } catch (const std::exception& e) {
        throw InternalError(fmt::format(
            "distributed: {} failed on rank {} of {} (another rank died or did not answer "
            "within {} s): {}",
            what, config_.rank, config_.world_size, config_.timeout_seconds, first_line(e)));
    }
}

namespace {

/// `tensors` split by dtype and device (name order kept within each part): each part travels
/// as one flat buffer, so a collective over tensors of one dtype is a single call.
std::map<std::string, ParamMap> by_dtype(const ParamMap& tensors) {
    std::map<std::string, ParamMap> parts;
    for (const auto& [name, t] : tensors)
        parts[std::string(c10::toString(t.scalar_type())) + "@" + t.device().str()][name] = t;
    return parts;
}

/// All tensors of one part as one contiguous 1-D buffer (a copy), in name order.
at::Tensor flatten(const ParamMap& tensors) {
    std::vector<at::Tensor> parts;
    parts.reserve(tensors.size());
    for (const auto& [name, t] : tensors) parts.push_back(t.detach().reshape(-1));
    return at::cat(parts);
}

/// Views of `buffer` shaped like the tensors of `like`, added to `out` under their names.
void unflatten(const at::Tensor& buffer, const ParamMap& like, ParamMap& out) {
    int64_t offset = 0;
    for (const auto& [name, t] : like) {
        out[name] = buffer.slice(0, offset, offset + t.numel()).view(t.sizes());
        offset += t.numel();
    }
}

}  // namespace

ParamMap ProcessGroup::sum(const ParamMap& tensors) { return reduce(tensors, 1); }

ParamMap ProcessGroup::average(const ParamMap& tensors) {
    return reduce(tensors, config_.world_size);
}

ParamMap ProcessGroup::reduce(const ParamMap& tensors, int64_t divisor) {
    if (!enabled()) return tensors;
    ParamMap result;
    for (const auto& [key, part] : by_dtype(tensors)) {
        at::Tensor buffer = flatten(part);
        run("all-reduce", [&](Backend& b) {
            std::vector<at::Tensor> buffers{buffer};
            b.group->allreduce(buffers)->wait();
        });
        if (divisor != 1 && buffer.is_floating_point())
            buffer.div_(divisor);
        else if (divisor != 1)
            buffer.div_(divisor, "floor");  // e.g. step counters, equal on every rank
        unflatten(buffer, part, result);
    }
    return result;
}

void ProcessGroup::broadcast(ParamMap& tensors) {
    if (!enabled()) return;
    for (const auto& [key, part] : by_dtype(tensors)) {
        at::Tensor buffer = flatten(part);
        run("broadcast", [&](Backend& b) {
            std::vector<at::Tensor> buffers{buffer};
            c10d::BroadcastOptions options;
            options.rootRank = 0;
            b.group->broadcast(buffers, options)->wait();
        });
        ParamMap received;
        unflatten(buffer, part, received);
        at::NoGradGuard no_grad;
        for (const auto& [name, t] : received) tensors.at(name).detach().copy_(t);
    }
}

bool ProcessGroup::identical(const ParamMap& tensors) {
    if (!enabled()) return true;
    auto h = static_cast<int64_t>(fingerprint(tensors));
    // max over ranks of (h, ~h) is (max h, ~min h): the ranks agree iff max h == min h.
    at::Tensor pair = at::tensor({h, ~h}, at::kLong).to(backend_->device);
    run("consistency check", [&](Backend& b) {
        std::vector<at::Tensor> buffers{pair};
        c10d::AllreduceOptions options;
        options.reduceOp = c10d::ReduceOp::MAX;
        b.group->allreduce(buffers, options)->wait();
    });
    pair = pair.cpu();
    return pair[0].item<int64_t>() == ~pair[1].item<int64_t>();
}

void ProcessGroup::barrier() {
    if (!enabled()) return;
    run("barrier", [](Backend& b) { b.group->barrier()->wait(); });
}

void start_in_sync(ProcessGroup& group, const nlohmann::json& counters, ParamMap& state) {
    if (!group.enabled()) return;
    ParamMap values;
    for (const auto& [name, value] : counters.items())
        values[name] = at::scalar_tensor(value.get<int64_t>(), at::kLong);
    if (!group.identical(values))
        throw_input_error("distributed",
                          "rank {} resumes at {} but another rank does not; "
                          "every rank must read rank 0's run directory",
                          group.rank(), counters.dump());
    group.broadcast(state);
}

}  // namespace pumeta
