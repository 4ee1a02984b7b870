#include "pumeta/models/torch_archive.h"

#include <ATen/ATen.h>
#include <caffe2/serialize/inline_container.h>
#include <gtest/gtest.h>

#include <cstring>
#include <filesystem>
#include <map>
#include <string>
#include <vector>

#include "pumeta/core/error.h"
#include "support/test_util.h"

namespace pumeta {
namespace {

namespace fs = std::filesystem;

/// Pickle bytes written opcode by opcode, as Python's pickler writes a state dict.
struct Pickle {
    std::string bytes = "\x80\x02";

    Pickle& op(char code) {
        bytes += code;
        return *this;
    }
    Pickle& op(uint8_t code) { return op(static_cast<char>(code)); }
    Pickle& global(const std::string& module, const std::string& name) {
        bytes += 'c' + module + '\n' + name + '\n';
        return *this;
    }
    Pickle& str(const std::string& text) {
        bytes += 'X';
        for (int i = 0; i < 4; ++i) bytes += static_cast<char>((text.size() >> (8 * i)) & 0xff);
        bytes += text;
        return *this;
    }
    Pickle& integer(int64_t value) {
        bytes += 'J';
        for (int i = 0; i < 4; ++i) bytes += static_cast<char>((value >> (8 * i)) & 0xff);
        return *this;
    }
    Pickle& ints(const std::vector<int64_t>& values) {
        op('(');
        for (int64_t v : values) integer(v);
        return op('t');
    }
};

/// One tensor entry of a state dict: a view (offset, size, stride) of storage `key`.
struct Entry {
    std::string name, key, type = "FloatStorage", location = "cpu";
    int64_t numel = 0, offset = 0;
    std::vector<int64_t> size, stride;
};

/// The pickle torch.save writes for an OrderedDict of these tensors, with _metadata.
std::string state_dict_pickle(const std::vector<Entry>& entries) {
    Pickle p;
    p.global("collections", "OrderedDict").op(')').op('R').op('q').op('\x00').op('(');
    for (const Entry& e : entries) {
        p.str(e.name).global("torch._utils", "_rebuild_tensor_v2").op('(');
        p.op('(').str("storage").global("torch", e.type).str(e.key).str(e.location);
        p.integer(e.numel).op('t').op('Q');
        p.integer(e.offset).ints(e.size).ints(e.stride).op(uint8_t{0x89});
        p.global("collections", "OrderedDict").op(')').op('R').op('t').op('R');
    }
    p.op('u');
    // The _metadata attribute: {"": {"version": 1}}, set by BUILD.
    p.op('}').str("").op('}').str("version").integer(1).op('s').op('s').op('b');
    return p.op('.').bytes;
}

/// A torch.save-style zip of `records` (names below the archive folder).
std::string archive(const std::map<std::string, std::string>& records) {
    std::string out;
    caffe2::serialize::PyTorchStreamWriter writer([&](const void* data, size_t size) {
        out.append(static_cast<const char*>(data), size);
        return size;
    });
    for (const auto& [name, bytes] : records) writer.writeRecord(name, bytes.data(), bytes.size());
    writer.writeEndOfFile();
    return out;
}

template <typename T>
std::string raw_bytes(const std::vector<T>& values) {
    return std::string(reinterpret_cast<const char*>(values.data()), values.size() * sizeof(T));
}

/// Two tensors viewing one float storage (the second transposed, at an offset) and an int64.
std::string sample_archive(const std::string& location = "cpu") {
    std::vector<float> floats(12);
    for (int i = 0; i < 12; ++i) floats[i] = 0.5f * static_cast<float>(i) - 1;
    const std::vector<Entry> entries = {
        {"conv.weight", "0", "FloatStorage", location, 12, 0, {2, 3}, {3, 1}},
        {"conv.view", "0", "FloatStorage", location, 12, 5, {3, 2}, {1, 3}},
        {"bn.num_batches_tracked", "1", "LongStorage", location, 1, 0, {}, {}},
    };
    return archive({{"data.pkl", state_dict_pickle(entries)},
                    {"data/0", raw_bytes(floats)},
                    {"data/1", raw_bytes(std::vector<int64_t>{42})}});
}

std::string refusal(const std::string& bytes) {
    try {
        parse_torch_state_dict("w.pth", bytes);
    } catch (const InputError& error) {
        return error.what();
    }
    return "read";
}

TEST(TorchArchive, ReadsEveryTensorOfAStateDictInOrderWithItsViewOfTheStorage) {
    for (const std::string location : {"cpu", "cuda:0"}) {
        const StateDict dict = parse_torch_state_dict("w.pth", sample_archive(location));
        ASSERT_EQ(dict.size(), 3u);
        EXPECT_EQ(dict[0].first, "conv.weight");
        EXPECT_EQ(dict[1].first, "conv.view");
        EXPECT_EQ(dict[2].first, "bn.num_batches_tracked");
        const at::Tensor storage = at::arange(12, at::kFloat) * 0.5 - 1;
        EXPECT_TRUE(at::equal(dict[0].second, storage.narrow(0, 0, 6).reshape({2, 3})));
        // Element (i, j) of the view is storage[5 + i + 3 j].
        EXPECT_TRUE(at::equal(dict[1].second, storage.as_strided({3, 2}, {1, 3}, 5)));
        EXPECT_TRUE(dict[1].second.is_contiguous());
        EXPECT_EQ(dict[2].second.scalar_type(), at::kLong);
        EXPECT_EQ(dict[2].second.dim(), 0);
        EXPECT_EQ(dict[2].second.item<int64_t>(), 42);
    }
}

TEST(TorchArchive, ReadsAFileFromDiskAndNamesAMissingOne) {
    test::TempDir dir;
    test::write_file(dir.file("w.pth"), sample_archive());
    EXPECT_EQ(read_torch_state_dict(dir.file("w.pth")).size(), 3u);
    try {
        read_torch_state_dict(dir.file("absent.pth"));
        FAIL() << "read a missing file";
    } catch (const InputError& error) {
        EXPECT_NE(std::string(error.what()).find("absent.pth: cannot be opened"),
                  std::string::npos);
    }
}

TEST(TorchArchive, RefusesForeignTruncatedAndForgedFilesWithOneLineNamingTheFault) {
    const Entry weight{"w", "0", "FloatStorage", "cpu", 4, 0, {4}, {1}};
    const std::string floats = raw_bytes(std::vector<float>{1, 2, 3, 4});
    auto with_pickle = [&](const std::string& pickle) {
        return archive({{"data.pkl", pickle}, {"data/0", floats}});
    };
    Entry past_end = weight;
    past_end.offset = 1;
    Entry wrong_numel = weight;
    wrong_numel.numel = 5;
    Entry double_storage = weight;
    double_storage.type = "DoubleStorage";
    const std::string good = with_pickle(state_dict_pickle({weight}));
    const std::vector<std::pair<std::string, std::string>> cases = {
        {"plain text\n", "not a torch.save archive"},
        {good.substr(0, good.size() / 2), "not a torch.save archive"},
        {archive({{"data/0", floats}}), "no record data.pkl"},
        {archive({{"data.pkl", state_dict_pickle({weight})}}), "no record data/0"},
        {with_pickle(state_dict_pickle({past_end})), "reaching element 4 of a storage of 4"},
        {with_pickle(state_dict_pickle({wrong_numel})), "holds 16 bytes, not the 20"},
        {with_pickle(state_dict_pickle({double_storage})), "global torch.DoubleStorage"},
        {with_pickle(Pickle().global("os", "system").op('.').bytes), "global os.system"},
        {with_pickle(Pickle().op('i').bytes), "opcode 0x69"},
        {with_pickle(Pickle().op(']').op('.').bytes), "holds a list, not a state dict"},
        {with_pickle(Pickle().op('}').str("a").integer(3).op('s').op('.').bytes),
         "entry 'a' is a int, not a tensor"},
        {with_pickle(Pickle().op('h').op('\x07').op('.').bytes), "memo entry 7"},
        {with_pickle(Pickle().op('}').op('.').bytes.substr(0, 3)), "ends before STOP"},
        {with_pickle(Pickle().op('}').op('u').op('.').bytes), "no mark"},
        {with_pickle(Pickle().op('s').op('.').bytes), "stack is empty"},
        {with_pickle(Pickle().op('X').bytes + "\xff\xff\xff\x7f"), "ends inside an opcode"},
    };
    for (const auto& [bytes, expected] : cases) {
        const std::string message = refusal(bytes);
        EXPECT_NE(message.find("w.pth: "), std::string::npos) << message;
        EXPECT_NE(message.find(expected), std::string::npos) << expected << " | " << message;
        EXPECT_EQ(message.find('\n'), std::string::npos) << message;
    }
}

TEST(TorchArchive, EveryPrefixAndEveryFlippedPickleByteIsReadOrRefusedNeverACrash) {
    const std::string good = sample_archive();
    for (size_t cut = 0; cut < good.size(); cut += 37)
        EXPECT_NE(refusal(good.substr(0, cut)), "read") << cut;
    std::vector<float> floats(12, 1.0f);
    const std::vector<Entry> entries = {{"a", "0", "FloatStorage", "cpu", 12, 0, {2, 3}, {3, 1}},
                                        {"b", "0", "FloatStorage", "cpu", 12, 5, {3, 2}, {1, 3}}};
    const std::string pickle = state_dict_pickle(entries);
    for (size_t i = 0; i < pickle.size(); ++i) {
        for (const uint8_t flip : {uint8_t{0x01}, uint8_t{0x80}, uint8_t{0xff}}) {
            std::string forged = pickle;
            forged[i] = static_cast<char>(static_cast<uint8_t>(forged[i]) ^ flip);
            try {
                unpickle_state_dict("w.pth", forged,
                                    [&](const std::string&) { return raw_bytes(floats); });
            } catch (const InputError&) {
            }
        }
    }
}

TEST(TorchArchive, DeepNestingAndRepeatedReferencesCostLittle) {
    // A tuple nested 200,000 deep and a tuple referenced 100,000 times: no recursion, no
    // copies.
    Pickle deep;
    deep.op(')');
    for (int i = 0; i < 200000; ++i) deep.op(uint8_t{0x85});
    deep.op('.');
    EXPECT_NE(refusal(archive({{"data.pkl", deep.bytes}})).find("holds a tuple"),
              std::string::npos);
    Pickle wide;
    wide.op(']').op('(').op('(');
    for (int i = 0; i < 1000; ++i) wide.integer(i);
    wide.op('t').op('q').op('\x01');
    for (int i = 0; i < 100000; ++i) wide.op('h').op('\x01');
    wide.op('e').op('.');
    EXPECT_NE(refusal(archive({{"data.pkl", wide.bytes}})).find("holds a list"), std::string::npos);
}

// The released files (skipped without ../shared): every entry read, the trained parameter
// counts the weights' documentation gives.
TEST(TorchArchive, ReadsTheReleasedGradPuAndPuGaussianWeights) {
    const fs::path weights = fs::path(test::source_dir()) / ".." / "shared" / "weights";
    if (!fs::exists(weights / "gradpu" / "pugan-ckpt-epoch-60.pth"))
        GTEST_SKIP() << "no " << weights.string();
    auto trained = [](const StateDict& dict) {
        int64_t count = 0;
        for (const auto& [name, tensor] : dict) {
            const bool statistic = name.find("running_") != std::string::npos ||
                                   name.find("num_batches_tracked") != std::string::npos;
            if (!statistic) count += tensor.numel();
        }
        return count;
    };
    for (const std::string file : {"pugan-ckpt-epoch-60.pth", "pu1k-ckpt-epoch-60.pth"}) {
        const StateDict dict = read_torch_state_dict((weights / "gradpu" / file).string());
        EXPECT_EQ(dict.size(), 288u) << file;
        EXPECT_EQ(trained(dict), 67073) << file;
        EXPECT_EQ(dict.front().first, "feature_extractor.conv_init.0.weight");
        EXPECT_TRUE(dict.front().second.isfinite().all().item<bool>());
    }
    const fs::path gaussian = weights / "pugaussian" / "pu_gaussian_pugan_Best.pth";
    if (fs::exists(gaussian)) {
        const StateDict dict = read_torch_state_dict(gaussian.string());
        EXPECT_EQ(dict.size(), 107u);
        EXPECT_EQ(trained(dict), 275086);
    }
}

}  // namespace
}  // namespace pumeta
