#include "pumeta/nn/sparse/coordinate_hash.h"

namespace pumeta {

namespace {

uint64_t capacity_for(int64_t count) {
    // Load factor at most 1/2 keeps linear probes short.
    uint64_t capacity = 16;
    while (capacity < uint64_t(count) * 2) capacity *= 2;
    return capacity;
}

}  // namespace

CoordinateHash::CoordinateHash(int64_t expected) { rehash(capacity_for(expected)); }

void CoordinateHash::rehash(uint64_t capacity) {
    std::vector<uint64_t> old_keys = std::move(keys_);
    std::vector<int64_t> old_rows = std::move(rows_);
    keys_.assign(capacity, kEmpty);
    rows_.assign(capacity, -1);
    mask_ = capacity - 1;
    size_ = 0;
    for (size_t i = 0; i < old_keys.size(); ++i)
        if (old_keys[i] != kEmpty) insert(old_keys[i], old_rows[i]);
}

int64_t CoordinateHash::insert(uint64_t key, int64_t row) {
    if (uint64_t(size_ + 1) * 2 > keys_.size()) rehash(keys_.size() * 2);
    uint64_t slot = mix(key) & mask_;
    while (true) {
        uint64_t stored = keys_[slot];
        if (stored == key) return rows_[slot];
        if (stored == kEmpty) {
            keys_[slot] = key;
            rows_[slot] = row;
            ++size_;
            return row;
        }
        slot = (slot + 1) & mask_;
    }
}

}  // namespace pumeta
