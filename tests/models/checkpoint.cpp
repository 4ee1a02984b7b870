#include "pumeta/models/checkpoint.h"

#include <ATen/ATen.h>
#include <gtest/gtest.h>

#include <filesystem>

#include "pumeta/core/error.h"
#include "pumeta/core/sha256.h"
#include "support/test_util.h"

namespace pumeta {

namespace {

nlohmann::json small_config() {
    return {{"backbone", "pugcn"},    {"channels", 4},    {"k", 4},
            {"upsample_channels", 8}, {"patch_size", 32}, {"seed", 11}};
}

at::Tensor patch(uint64_t seed) {
    at::Generator gen = at::detail::createCPUGenerator(seed);
    return at::rand({2, 32, 3}, gen);
}

// The message of the InputError that loading `path` throws ("" when none).
std::string load_error(const std::string& path) {
    try {
        load_checkpoint(path);
    } catch (const InputError& e) {
        return e.what();
    }
    return "";
}

bool contains(const std::string& text, const std::string& part) {
    return text.find(part) != std::string::npos;
}

// The checkpoint `bytes` with its header edited and its hash recomputed, as a file edited by
// hand (or by a fuzzer) would be.
template <class Edit>
std::string resealed(const std::string& bytes, Edit edit) {
    const size_t magic = std::string("PUMETA-CKPT\n").size();
    const size_t end = bytes.find('\n', magic);
    nlohmann::json header = nlohmann::json::parse(bytes.substr(magic, end - magic));
    edit(header);
    header.erase("sha256");
    const std::string payload = bytes.substr(end + 1);
    Sha256 hash;
    const std::string text = header.dump() + "\n";
    hash.update(text.data(), text.size());
    hash.update(payload.data(), payload.size());
    header["sha256"] = hash.hex_digest();
    return bytes.substr(0, magic) + header.dump() + "\n" + payload;
}

}  // namespace

TEST(Checkpoint, RoundTripRebuildsTheBackboneWithIdenticalOutputs) {
    test::TempDir dir;
    std::unique_ptr<Backbone> model = make_backbone(small_config());
    {
        // Trained-looking weights, not the seed's initialisation, must survive.
        at::NoGradGuard no_grad;
        for (auto& [name, p] : model->parameters()) p.add_(0.01);
    }
    nlohmann::json extra = {{"step", 1234}, {"note", "after pretraining"}};
    save_checkpoint(dir.file("model.ckpt"), *model, extra);

    LoadedCheckpoint loaded = load_checkpoint(dir.file("model.ckpt"));
    EXPECT_EQ(loaded.extra, extra);
    EXPECT_EQ(loaded.backbone->config(), model->config());
    for (const auto& [name, p] : model->parameters()) {
        const at::Tensor& q = loaded.backbone->parameters().at(name);
        EXPECT_TRUE(q.equal(p)) << name;
        EXPECT_TRUE(q.requires_grad()) << name;
    }
    at::NoGradGuard no_grad;
    at::Tensor x = patch(1);
    EXPECT_TRUE(loaded.backbone->upsample(x).equal(model->upsample(x)));
    // Only the checkpoint is left: the temporary file was renamed.
    EXPECT_EQ(std::distance(std::filesystem::directory_iterator(dir.path()), {}), 1);
}

TEST(Checkpoint, OverwritingReplacesTheFile) {
    test::TempDir dir;
    std::unique_ptr<Backbone> model = make_backbone(small_config());
    save_checkpoint(dir.file("m.ckpt"), *model, {{"step", 1}});
    save_checkpoint(dir.file("m.ckpt"), *model, {{"step", 2}});
    EXPECT_EQ(load_checkpoint(dir.file("m.ckpt")).extra["step"], 2);
}

TEST(Checkpoint, FlippedBytesAnywhereAreReportedAsCorruption) {
    test::TempDir dir;
    std::unique_ptr<Backbone> model = make_backbone(small_config());
    save_checkpoint(dir.file("m.ckpt"), *model);
    const std::string bytes = test::read_file(dir.file("m.ckpt"));
    // A payload byte (end of file), and a digit of the stored loss_scale in the header, which
    // would otherwise load as a silently different model.
    size_t header_digit = bytes.find("\"loss_scale\":1.0") + std::string("\"loss_scale\":").size();
    for (size_t position : {bytes.size() - 5, header_digit}) {
        std::string corrupted = bytes;
        corrupted[position] ^= 0x01;
        test::write_file(dir.file("bad.ckpt"), corrupted);
        std::string message = load_error(dir.file("bad.ckpt"));
        EXPECT_EQ(message, dir.file("bad.ckpt") + ": checkpoint is corrupted (SHA-256 mismatch)")
            << "byte " << position;
    }
    std::string broken_json = bytes;
    broken_json[bytes.find('{')] = '[';
    test::write_file(dir.file("bad.ckpt"), broken_json);
    EXPECT_TRUE(contains(load_error(dir.file("bad.ckpt")), "checkpoint is corrupted"));
}

TEST(Checkpoint, TruncatedWrongMagicAndMissingFilesAreInputErrors) {
    test::TempDir dir;
    std::unique_ptr<Backbone> model = make_backbone(small_config());
    save_checkpoint(dir.file("m.ckpt"), *model);
    const std::string bytes = test::read_file(dir.file("m.ckpt"));

    test::write_file(dir.file("short.ckpt"), bytes.substr(0, bytes.size() - 100));
    EXPECT_TRUE(
        contains(load_error(dir.file("short.ckpt")), "short.ckpt: checkpoint is truncated"));
    test::write_file(dir.file("header.ckpt"), bytes.substr(0, 40));
    EXPECT_TRUE(contains(load_error(dir.file("header.ckpt")), "checkpoint is truncated"));
    test::write_file(dir.file("magic.ckpt"), "PUMETA-CKPX" + bytes.substr(11));
    EXPECT_TRUE(
        contains(load_error(dir.file("magic.ckpt")), "magic.ckpt: not a pumeta checkpoint"));
    test::write_file(dir.file("empty.ckpt"), "");
    EXPECT_TRUE(contains(load_error(dir.file("empty.ckpt")), "empty.ckpt: file is empty"));
    EXPECT_TRUE(contains(load_error(dir.file("missing.ckpt")), "missing.ckpt: file not found"));
}

// Found by fuzzing: a number beyond double's range made the JSON parser throw an exception
// other than its parse error, which escaped as an internal error.
TEST(Checkpoint, AHeaderNumberOutOfRangeIsCorruption) {
    test::TempDir dir;
    test::write_file(dir.file("huge.ckpt"), "PUMETA-CKPT\n{\"format_version\": 1e4308}\n");
    EXPECT_TRUE(contains(load_error(dir.file("huge.ckpt")),
                         "huge.ckpt: checkpoint is corrupted (header is not valid JSON)"));
}

// A header edited by hand and its hash recomputed (what a fuzzer or a forger does): the stored
// config asks for a network far larger than the file's tensors, which must fail before the
// network is allocated (a PU-GCN of width 60,000 would need tens of GiB).
TEST(Checkpoint, AConfigLargerThanTheFileIsRefusedBeforeAllocating) {
    test::TempDir dir;
    save_checkpoint(dir.file("m.ckpt"), *make_backbone(small_config()));
    test::write_file(dir.file("forged.ckpt"),
                     resealed(test::read_file(dir.file("m.ckpt")), [](nlohmann::json& header) {
                         header["config"]["channels"] = 60000;
                     }));
    const std::string message = load_error(dir.file("forged.ckpt"));
    EXPECT_TRUE(contains(message, "forged.ckpt: stored config cannot be rebuilt")) << message;
    EXPECT_TRUE(contains(message, "larger than the file's tensors")) << message;
    // The same bytes in memory.
    EXPECT_THROW(parse_checkpoint("forged.ckpt", test::read_file(dir.file("forged.ckpt"))),
                 InputError);
}

// Found by fuzzing: a tensor offset written as a float beyond 2^64 was converted to an integer
// (undefined behaviour) before any check.
TEST(Checkpoint, NonIntegerTensorFieldsAreCorruption) {
    test::TempDir dir;
    save_checkpoint(dir.file("m.ckpt"), *make_backbone(small_config()));
    const std::string bytes = test::read_file(dir.file("m.ckpt"));
    for (const char* field : {"offset", "nbytes", "shape"}) {
        test::write_file(dir.file("forged.ckpt"), resealed(bytes, [&](nlohmann::json& header) {
                             nlohmann::json& entry = header["tensors"]["out.fc2.bias"];
                             entry[field] = std::string(field) == "shape"
                                                ? nlohmann::json::array({2.3e93})
                                                : nlohmann::json(2.3e93);
                         }));
        EXPECT_TRUE(contains(load_error(dir.file("forged.ckpt")),
                             "tensor 'out.fc2.bias' has a non-integer shape, offset or size"))
            << field;
    }
}

TEST(Checkpoint, TensorsThatDoNotFitTheBackboneAreNamed) {
    test::TempDir dir;
    auto error_after = [&](auto edit) {
        std::unique_ptr<Backbone> model = make_backbone(small_config());
        edit(model->parameters());
        save_checkpoint(dir.file("m.ckpt"), *model);
        return load_error(dir.file("m.ckpt"));
    };
    EXPECT_TRUE(contains(error_after([](ParamMap& p) { p["out.fc2.bias"] = at::zeros({4}); }),
                         "tensor 'out.fc2.bias' has shape [4], backbone pugcn expects [3]"));
    EXPECT_TRUE(contains(error_after([](ParamMap& p) { p.erase("head.message.bias"); }),
                         "lacks tensor 'head.message.bias'"));
    EXPECT_TRUE(contains(error_after([](ParamMap& p) { p["extra.weight"] = at::zeros({2}); }),
                         "tensor 'extra.weight' does not belong to backbone pugcn"));
}

TEST(TensorFile, RoundTripKeepsDtypesShapesAndValues) {
    test::TempDir dir;
    ParamMap tensors;
    tensors["adam.m"] = at::randn({3, 4}, at::kFloat);
    tensors["adam.v"] = at::randn({5}, at::kDouble).t();
    tensors["strided"] = at::arange(12, at::kLong).view({3, 4}).t();  // non-contiguous
    tensors["int"] = at::tensor({-1, 7}, at::kInt);
    tensors["bytes"] = at::tensor({0, 255}, at::kByte);
    tensors["mask"] = at::tensor({1, 0}, at::kByte).to(at::kBool);
    tensors["empty"] = at::zeros({0, 3});
    tensors["scalar"] = at::tensor(2.5);
    nlohmann::json extra = {{"step", 7}, {"betas", {0.9, 0.999}}};
    save_tensors(dir.file("state.bin"), tensors, extra);

    TensorFile loaded = load_tensors(dir.file("state.bin"));
    EXPECT_EQ(loaded.extra, extra);
    ASSERT_EQ(loaded.tensors.size(), tensors.size());
    for (const auto& [name, tensor] : tensors) {
        const at::Tensor& back = loaded.tensors.at(name);
        EXPECT_EQ(back.scalar_type(), tensor.scalar_type()) << name;
        EXPECT_TRUE(back.equal(tensor)) << name;
    }
}

TEST(TensorFile, BackboneCheckpointsAndTensorFilesAreNotInterchangeable) {
    test::TempDir dir;
    save_tensors(dir.file("state.bin"), {{"x", at::zeros({2})}});
    EXPECT_TRUE(contains(load_error(dir.file("state.bin")), "is not a backbone checkpoint"));
    save_checkpoint(dir.file("m.ckpt"), *make_backbone(small_config()));
    EXPECT_THROW(load_tensors(dir.file("m.ckpt")), InputError);
}

TEST(TensorFile, UnwritableDestinationIsAnInputError) {
    test::TempDir dir;
    EXPECT_THROW(save_tensors(dir.file("no/such/dir/state.bin"), {{"x", at::zeros({1})}}),
                 InputError);
}

}  // namespace pumeta
