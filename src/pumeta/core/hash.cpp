#include "pumeta/core/hash.h"

#include <string>

namespace pumeta {

namespace {

uint64_t splitmix64(uint64_t h) {
    h ^= h >> 30;
    h *= 0xbf58476d1ce4e5b9ull;
    h ^= h >> 27;
    h *= 0x94d049bb133111ebull;
    return h ^ (h >> 31);
}

}  // namespace

uint64_t stable_hash(std::string_view text) {
    uint64_t h = 1469598103934665603ull;
    for (unsigned char c : text) h = (h ^ c) * 1099511628211ull;
    return splitmix64(h);
}

uint64_t derive_seed(uint64_t seed, std::string_view purpose) {
    return splitmix64(stable_hash(purpose) ^ splitmix64(seed + 0x9e3779b97f4a7c15ull));
}

double hash_fraction(std::string_view text) {
    return static_cast<double>(stable_hash(text) >> 11) * 0x1.0p-53;
}

}  // namespace pumeta
