// A hash map from voxel coordinates (batch, x, y, z) to row indices: the lookup behind every
// sparse kernel map. Keys are packed into 64 bits, the table is open-addressed with linear
// probing, and lookups are read-only, so kernel maps are built with parallel lookups.
#pragma once

#include <cstdint>
#include <vector>

namespace pumeta {

/// Coordinates must lie in [kMinCoordinate, kMaxCoordinate] and batch indices in
/// [0, kMaxBatch]: 16 bits each in the packed key.
constexpr int64_t kMinCoordinate = -32768;
constexpr int64_t kMaxCoordinate = 32767;
constexpr int64_t kMaxBatch = 65534;

/// Whether (batch, x, y, z) is in the packable range.
inline bool packable(int64_t batch, int64_t x, int64_t y, int64_t z) {
    return batch >= 0 && batch <= kMaxBatch && x >= kMinCoordinate && x <= kMaxCoordinate &&
           y >= kMinCoordinate && y <= kMaxCoordinate && z >= kMinCoordinate && z <= kMaxCoordinate;
}

/// The 64-bit key of a packable coordinate: 16 bits each, biased to unsigned. Batch 65535 is
/// never packed, so the all-ones key can mark empty slots.
inline uint64_t pack_coordinate(int64_t batch, int64_t x, int64_t y, int64_t z) {
    return (uint64_t(batch) << 48) | (uint64_t(x - kMinCoordinate) << 32) |
           (uint64_t(y - kMinCoordinate) << 16) | uint64_t(z - kMinCoordinate);
}

/// Packed key -> row (int64 >= 0). Not thread-safe for insert; find() may run concurrently.
class CoordinateHash {
  public:
    /// An empty map sized for about `expected` keys (it grows when needed).
    explicit CoordinateHash(int64_t expected = 0);

    /// Inserts key -> row unless the key is present; returns the row stored for the key (the
    /// new one, or the existing one).
    int64_t insert(uint64_t key, int64_t row);

    /// The row of `key`, or -1.
    int64_t find(uint64_t key) const {
        uint64_t slot = mix(key) & mask_;
        while (true) {
            uint64_t stored = keys_[slot];
            if (stored == key) return rows_[slot];
            if (stored == kEmpty) return -1;
            slot = (slot + 1) & mask_;
        }
    }

    int64_t size() const { return size_; }

  private:
    static constexpr uint64_t kEmpty = ~uint64_t(0);

    /// SplitMix64's finaliser: packed keys of neighbouring voxels differ in a few low bits of
    /// each 16-bit field, which a plain modulo would cluster.
    static uint64_t mix(uint64_t key) {
        key ^= key >> 30;
        key *= 0xbf58476d1ce4e5b9ULL;
        key ^= key >> 27;
        key *= 0x94d049bb133111ebULL;
        key ^= key >> 31;
        return key;
    }

    void rehash(uint64_t capacity);

    std::vector<uint64_t> keys_;
    std::vector<int64_t> rows_;
    uint64_t mask_ = 0;
    int64_t size_ = 0;
};

}  // namespace pumeta
