#include "pumeta/core/sha256.h"

#include <gtest/gtest.h>

#include <string>

#include "pumeta/core/error.h"
#include "support/test_util.h"

namespace pumeta {

// Test vectors from FIPS 180-4 / NIST's SHA-256 examples.
TEST(Sha256, StandardTestVectors) {
    EXPECT_EQ(sha256_hex(""), "e3b0c44298fc1c149afbf4c8996fb92427ae41e4649b934ca495991b7852b855");
    EXPECT_EQ(sha256_hex("abc"),
              "ba7816bf8f01cfea414140de5dae2223b00361a396177a9cb410ff61f20015ad");
    EXPECT_EQ(sha256_hex("abcdbcdecdefdefgefghfghighijhijkijkljklmklmnlmnomnopnopq"),
              "248d6a61d20638b8e5c026930c3e6039a33ce45964ff2167f6ecedd419db06c1");
    EXPECT_EQ(sha256_hex(std::string(1000000, 'a')),
              "cdc76e5c9914fb9281a1c7e284d73e67f1809a48a497200e046d39ccc7112cd0");
}

TEST(Sha256, IncrementalUpdatesMatchOneShotForEverySplit) {
    // Lengths around the 55/56/64-byte padding boundaries exercise every padding branch.
    std::string message;
    for (int i = 0; i < 130; ++i) message += char('a' + i % 26);
    for (size_t length : {55, 56, 63, 64, 65, 119, 120, 130}) {
        std::string prefix = message.substr(0, length);
        std::string expected = sha256_hex(prefix);
        for (size_t split = 0; split <= length; split += 7) {
            Sha256 hash;
            hash.update(prefix.data(), split);
            hash.update(prefix.data() + split, length - split);
            EXPECT_EQ(hash.hex_digest(), expected) << "length " << length << " split " << split;
        }
    }
}

TEST(Sha256, FileHashEqualsBufferHashAndMissingFileIsInputError) {
    test::TempDir dir;
    std::string bytes(3 << 20, '\0');  // larger than the 1 MiB read block
    for (size_t i = 0; i < bytes.size(); ++i) bytes[i] = char(i * 2654435761u >> 13);
    test::write_file(dir.file("blob.bin"), bytes);
    EXPECT_EQ(sha256_file(dir.file("blob.bin")), sha256_hex(bytes));
    EXPECT_THROW(sha256_file(dir.file("missing.bin")), InputError);
}

}  // namespace pumeta
