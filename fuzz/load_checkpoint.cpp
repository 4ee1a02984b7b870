// libFuzzer target: the checkpoint loader. A mutated file fails its SHA-256 check, which
// would stop every input at the hash; so an input whose header parses is resealed first (its
// hash recomputed, as a file written by hand would be), and the loader's checks behind the
// hash (header fields, tensor table, payload bounds, the stored config rebuilding a network)
// are reached too. Inputs that do not parse go to the loader unchanged.
#include <nlohmann/json.hpp>

#include "fuzz/contract.h"
#include "pumeta/core/sha256.h"
#include "pumeta/models/checkpoint.h"

namespace {

constexpr std::string_view kMagic = "PUMETA-CKPT\n";

std::string reseal(std::string_view bytes) {
    if (bytes.substr(0, kMagic.size()) != kMagic) return std::string(bytes);
    const size_t header_end = bytes.find('\n', kMagic.size());
    if (header_end == std::string_view::npos) return std::string(bytes);
    nlohmann::json header =
        nlohmann::json::parse(bytes.substr(kMagic.size(), header_end - kMagic.size()), nullptr,
                              /*allow_exceptions=*/false);
    if (!header.is_object()) return std::string(bytes);
    const std::string_view payload = bytes.substr(header_end + 1);
    header.erase("sha256");
    const std::string text = header.dump() + "\n";
    pumeta::Sha256 hash;
    hash.update(text.data(), text.size());
    hash.update(payload.data(), payload.size());
    header["sha256"] = hash.hex_digest();
    return std::string(kMagic) + header.dump() + "\n" + std::string(payload);
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
    return pumeta::fuzz::run(data, size, [](std::string_view bytes) {
        const std::string resealed = reseal(bytes);
        pumeta::LoadedCheckpoint loaded = pumeta::parse_checkpoint("input.pt", resealed);
        if (!loaded.backbone) pumeta::fuzz::violated("a checkpoint loaded without a backbone");
    });
}
