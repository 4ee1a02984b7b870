#include "pumeta/models/checkpoint.h"

#include <ATen/ATen.h>
#include <fcntl.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <filesystem>
#include <vector>

#include "pumeta/core/error.h"
#include "pumeta/core/sha256.h"
#include "pumeta/core/tensor_checks.h"
#include "pumeta/geometry/io/file.h"

namespace pumeta {

namespace {

constexpr char kMagic[] = "PUMETA-CKPT\n";
constexpr size_t kMagicSize = sizeof(kMagic) - 1;
constexpr int kFormatVersion = 1;
// Backbone buffers (e.g. batch-norm running statistics) are stored as "buffers/<name>" next to
// the parameters; files without such entries load into backbones without buffers as before.
constexpr char kBufferPrefix[] = "buffers/";

struct DtypeName {
    at::ScalarType type;
    const char* name;
};
constexpr DtypeName kDtypes[] = {{at::kFloat, "float32"}, {at::kDouble, "float64"},
                                 {at::kLong, "int64"},    {at::kInt, "int32"},
                                 {at::kByte, "uint8"},    {at::kBool, "bool"}};

void require_little_endian() {
    const uint16_t probe = 1;
    if (*reinterpret_cast<const uint8_t*>(&probe) != 1)
        throw InternalError("checkpoints are little-endian; big-endian hosts are not supported");
}

const char* dtype_name(at::ScalarType type, const std::string& path, const std::string& tensor) {
    for (const auto& entry : kDtypes)
        if (entry.type == type) return entry.name;
    throw_input_error(path, "cannot store tensor '{}' of type {}", tensor,
                      std::string(c10::toString(type)));
}

// The hashed bytes: the header without its hash, then the payload.
std::string content_hash(nlohmann::json header, const char* payload, size_t size) {
    header.erase("sha256");
    Sha256 hash;
    std::string text = header.dump() + "\n";
    hash.update(text.data(), text.size());
    hash.update(payload, size);
    return hash.hex_digest();
}

void write_all(int fd, const char* data, size_t size, const std::string& path) {
    while (size > 0) {
        ssize_t written = ::write(fd, data, size);
        if (written < 0 && errno == EINTR) continue;
        if (written <= 0)
            throw_input_error(path, "cannot write checkpoint: {}", std::strerror(errno));
        data += written;
        size -= size_t(written);
    }
}

// Writes to a temporary file in the destination's directory, syncs it and renames it over
// `path`, so a crash leaves either the old file or the complete new one.
void write_atomically(const std::string& path, const std::string& header,
                      const std::string& payload) {
    std::string pattern = path + ".tmp-XXXXXX";
    std::vector<char> temp(pattern.begin(), pattern.end());
    temp.push_back('\0');
    int fd = ::mkstemp(temp.data());
    if (fd < 0) throw_input_error(path, "cannot write checkpoint: {}", std::strerror(errno));
    try {
        write_all(fd, kMagic, kMagicSize, path);
        write_all(fd, header.data(), header.size(), path);
        write_all(fd, payload.data(), payload.size(), path);
        if (::fsync(fd) != 0)
            throw_input_error(path, "cannot write checkpoint: {}", std::strerror(errno));
        if (::close(fd) != 0) {
            fd = -1;
            throw_input_error(path, "cannot write checkpoint: {}", std::strerror(errno));
        }
        fd = -1;
        std::error_code error;
        std::filesystem::rename(temp.data(), path, error);
        if (error) throw_input_error(path, "cannot write checkpoint: {}", error.message());
    } catch (...) {
        if (fd >= 0) ::close(fd);
        std::error_code ignored;
        std::filesystem::remove(temp.data(), ignored);
        throw;
    }
}

void save_container(const std::string& path, const std::string& content,
                    const nlohmann::json& config, const ParamMap& tensors,
                    const nlohmann::json& extra) {
    require_little_endian();
    nlohmann::json table = nlohmann::json::object();
    std::string payload;
    for (const auto& [name, tensor] : tensors) {
        at::Tensor data = tensor.detach().to(at::kCPU).contiguous();
        size_t nbytes = data.numel() * data.element_size();
        table[name] = {{"dtype", dtype_name(data.scalar_type(), path, name)},
                       {"shape", data.sizes().vec()},
                       {"offset", payload.size()},
                       {"nbytes", nbytes}};
        payload.append(static_cast<const char*>(data.data_ptr()), nbytes);
    }
    nlohmann::json header = {{"format_version", kFormatVersion},
                             {"content", content},
                             {"extra", extra},
                             {"tensors", table},
                             {"payload_bytes", payload.size()}};
    if (!config.is_null()) header["config"] = config;
    header["sha256"] = content_hash(header, payload.data(), payload.size());
    write_atomically(path, header.dump() + "\n", payload);
}

struct Container {
    nlohmann::json header;
    ParamMap tensors;
};

int64_t stored_elements(const ParamMap& tensors) {
    int64_t total = 0;
    for (const auto& [name, tensor] : tensors) total += tensor.numel();
    return total;
}

at::Tensor read_tensor(const std::string& path, const std::string& name,
                       const nlohmann::json& entry, std::string_view payload) {
    try {
        at::ScalarType type = at::kFloat;
        bool known = false;
        for (const auto& dtype : kDtypes)
            if (entry.at("dtype") == dtype.name) {
                type = dtype.type;
                known = true;
            }
        if (!known)
            throw_input_error(path, "tensor '{}' has unknown dtype {}", name,
                              entry.at("dtype").dump());
        // Types first: converting a JSON float such as 2.3e93 to an integer is undefined.
        const nlohmann::json& dims = entry.at("shape");
        bool valid = dims.is_array() && entry.at("offset").is_number_unsigned() &&
                     entry.at("nbytes").is_number_unsigned();
        for (const nlohmann::json& dim : dims) valid = valid && dim.is_number_integer();
        if (!valid)
            throw_input_error(path, "tensor '{}' has a non-integer shape, offset or size", name);
        std::vector<int64_t> shape = dims.get<std::vector<int64_t>>();
        size_t offset = entry.at("offset").get<size_t>();
        size_t nbytes = entry.at("nbytes").get<size_t>();
        // The shape's size is checked against the payload before anything is allocated.
        uint64_t expected = c10::elementSize(type);
        for (int64_t dim : shape)
            if (dim < 0 || __builtin_mul_overflow(expected, static_cast<uint64_t>(dim), &expected))
                throw_input_error(path, "tensor '{}' has an invalid shape {}", name,
                                  entry.at("shape").dump());
        if (expected != nbytes || offset > payload.size() || nbytes > payload.size() - offset)
            throw_input_error(path, "tensor '{}' does not fit the payload", name);
        at::Tensor tensor = at::empty(shape, at::TensorOptions().dtype(type));
        if (nbytes > 0) std::memcpy(tensor.data_ptr(), payload.data() + offset, nbytes);
        return tensor;
    } catch (const nlohmann::json::exception& e) {
        throw_input_error(path, "tensor '{}' has an invalid entry: {}", name, e.what());
    } catch (const c10::Error&) {
        throw_input_error(path, "tensor '{}' has an invalid shape {}", name,
                          entry.at("shape").dump());
    }
}

Container parse_container(const std::string& path, std::string_view bytes) {
    require_little_endian();
    if (bytes.compare(0, kMagicSize, kMagic) != 0)
        throw_input_error(path, "not a pumeta checkpoint (missing \"PUMETA-CKPT\" header)");
    size_t header_end = bytes.find('\n', kMagicSize);
    if (header_end == std::string::npos)
        throw_input_error(path, "checkpoint is truncated (incomplete header)");

    Container container;
    nlohmann::json& header = container.header;
    try {
        header = nlohmann::json::parse(bytes.begin() + kMagicSize, bytes.begin() + header_end);
    } catch (const nlohmann::json::exception&) {  // syntax, or a number out of range
        throw_input_error(path, "checkpoint is corrupted (header is not valid JSON)");
    }
    if (!header.is_object() || !header.contains("format_version"))
        throw_input_error(path, "checkpoint is corrupted (header lacks format_version)");
    if (header["format_version"] != kFormatVersion)
        throw_input_error(path, "unsupported checkpoint format version {} (this build reads {})",
                          header["format_version"].dump(), kFormatVersion);
    const std::string_view payload = bytes.substr(header_end + 1);
    if (!header.contains("payload_bytes") || !header["payload_bytes"].is_number_unsigned() ||
        !header.contains("sha256") || !header["sha256"].is_string() ||
        !header.contains("tensors") || !header["tensors"].is_object() ||
        (header.contains("content") && !header["content"].is_string()))
        throw_input_error(path, "checkpoint is corrupted (incomplete header)");
    const size_t expected = header["payload_bytes"].get<size_t>();
    if (payload.size() < expected)
        throw_input_error(path, "checkpoint is truncated ({} of {} payload bytes)", payload.size(),
                          expected);
    if (payload.size() > expected ||
        content_hash(header, payload.data(), payload.size()) != header["sha256"])
        throw_input_error(path, "checkpoint is corrupted (SHA-256 mismatch)");
    for (const auto& [name, entry] : header["tensors"].items())
        container.tensors[name] = read_tensor(path, name, entry, payload);
    return container;
}

Container load_container(const std::string& path) {
    return parse_container(path, io::read_whole_file(path));
}

}  // namespace

void save_tensors(const std::string& path, const ParamMap& tensors, const nlohmann::json& extra) {
    save_container(path, "tensors", nullptr, tensors, extra);
}

TensorFile load_tensors(const std::string& path) {
    Container container = load_container(path);
    if (container.header.value("content", "") != "tensors")
        throw_input_error(path, "holds a {} checkpoint, not plain tensors",
                          container.header.value("content", "?"));
    return {std::move(container.tensors), container.header.value("extra", nlohmann::json())};
}

void save_checkpoint(const std::string& path, const Backbone& backbone,
                     const nlohmann::json& extra) {
    ParamMap tensors = backbone.parameters();
    for (const auto& [name, buffer] : backbone.buffers()) tensors[kBufferPrefix + name] = buffer;
    save_container(path, "backbone", backbone.config(), tensors, extra);
}

LoadedCheckpoint load_checkpoint(const std::string& path) {
    return parse_checkpoint(path, io::read_whole_file(path));
}

LoadedCheckpoint parse_checkpoint(const std::string& path, std::string_view bytes) {
    Container container = parse_container(path, bytes);
    if (container.header.value("content", "") != "backbone" || !container.header.contains("config"))
        throw_input_error(path, "is not a backbone checkpoint");
    LoadedCheckpoint loaded;
    try {
        // Generous (twice the file, plus 4 MiB), so that a file lacking a tensor still gets the
        // message naming it; a forged config asking for GiBs fails here.
        ParameterBudget budget(2 * stored_elements(container.tensors) + (1 << 20), "config");
        loaded.backbone = make_backbone(container.header["config"]);
    } catch (const InputError& e) {
        throw_input_error(path, "stored config cannot be rebuilt: {}", e.what());
    } catch (const nlohmann::json::exception& e) {
        throw_input_error(path, "stored config cannot be rebuilt: {}", e.what());
    }
    const std::string kind = loaded.backbone->name();
    ParamMap& params = loaded.backbone->parameters();
    ParamMap& buffers = loaded.backbone->buffers();
    const std::string buffer_prefix = kBufferPrefix;
    for (const auto& [name, stored] : container.tensors) {
        bool is_buffer = name.rfind(buffer_prefix, 0) == 0;
        if (is_buffer ? !buffers.count(name.substr(buffer_prefix.size())) : !params.count(name))
            throw_input_error(path, "tensor '{}' does not belong to backbone {}", name, kind);
    }
    at::NoGradGuard no_grad;
    for (auto& [name, tensor] : params) {
        auto it = container.tensors.find(name);
        if (it == container.tensors.end())
            throw_input_error(path, "lacks tensor '{}' of backbone {}", name, kind);
        if (!it->second.sizes().equals(tensor.sizes()))
            throw_input_error(path, "tensor '{}' has shape {}, backbone {} expects {}", name,
                              shape_string(it->second), kind, shape_string(tensor));
        tensor.copy_(it->second);
    }
    for (auto& [name, buffer] : buffers) {
        auto it = container.tensors.find(buffer_prefix + name);
        if (it == container.tensors.end())
            throw_input_error(path, "lacks buffer '{}' of backbone {}", name, kind);
        if (!it->second.sizes().equals(buffer.sizes()))
            throw_input_error(path, "buffer '{}' has shape {}, backbone {} expects {}", name,
                              shape_string(it->second), kind, shape_string(buffer));
        buffer = it->second.to(buffer.scalar_type());
    }
    loaded.extra = container.header.value("extra", nlohmann::json());
    return loaded;
}

}  // namespace pumeta
