// SHA-256 (FIPS 180-4), used to detect corrupted checkpoints.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <string>

namespace pumeta {

/// Incremental SHA-256: update() any number of times, then hex_digest() once.
class Sha256 {
  public:
    Sha256();

    void update(const void* data, size_t size);
    /// Pads, finishes and returns the 32-byte digest. The object must not be updated afterwards.
    std::array<uint8_t, 32> digest();
    /// digest() as 64 lowercase hex characters.
    std::string hex_digest();

  private:
    void process_block(const uint8_t* block);

    std::array<uint32_t, 8> state_;
    std::array<uint8_t, 64> buffer_;
    size_t buffered_ = 0;
    uint64_t total_bytes_ = 0;
    bool finished_ = false;
};

/// Hex SHA-256 of a byte range.
std::string sha256_hex(const void* data, size_t size);
inline std::string sha256_hex(const std::string& bytes) {
    return sha256_hex(bytes.data(), bytes.size());
}

/// Hex SHA-256 of a file's contents, read in blocks; InputError when it cannot be read.
std::string sha256_file(const std::string& path);

}  // namespace pumeta
