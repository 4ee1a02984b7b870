// Stable, platform-independent hashing for deterministic splits and derived seeds.
#pragma once

#include <cstdint>
#include <string_view>

namespace pumeta {

/// FNV-1a followed by a SplitMix64 finaliser: the same 64 bits on every platform and run.
uint64_t stable_hash(std::string_view text);

/// A seed for one purpose derived from a base seed, e.g. derive_seed(seed, "bed1/gt/x4").
uint64_t derive_seed(uint64_t seed, std::string_view purpose);

/// The hash as a fraction in [0, 1).
double hash_fraction(std::string_view text);

}  // namespace pumeta
