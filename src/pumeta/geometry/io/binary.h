// Loading and storing fixed-size scalars from raw file bytes in either byte order.
#pragma once

#include <cstddef>
#include <cstdint>
#include <cstring>

namespace pumeta::io {

// The fast paths copy little-endian file data straight into tensors.
static_assert(__BYTE_ORDER__ == __ORDER_LITTLE_ENDIAN__,
              "pumeta's readers assume a little-endian host");

/// The T stored at `bytes`; `swap` reverses its bytes (big-endian data on this host).
template <typename T>
T load(const char* bytes, bool swap = false) {
    T value;
    if (!swap) {
        std::memcpy(&value, bytes, sizeof(T));
        return value;
    }
    char reversed[sizeof(T)];
    for (size_t i = 0; i < sizeof(T); ++i) reversed[i] = bytes[sizeof(T) - 1 - i];
    std::memcpy(&value, reversed, sizeof(T));
    return value;
}

/// Appends `value` in little-endian byte order.
template <typename T, typename Buffer>
void append_le(Buffer& out, T value) {
    char bytes[sizeof(T)];
    std::memcpy(bytes, &value, sizeof(T));
    out.append(bytes, sizeof(T));
}

}  // namespace pumeta::io
