// The distributed sampler (PatchLoader shards): the shards of all ranks, concatenated in rank
// order, must be bit-identical to the unsharded batch, for every input sampler, with and
// without augmentation, across epoch boundaries and after seek().
#include <ATen/ATen.h>
#include <gtest/gtest.h>

#include "pumeta/core/error.h"
#include "pumeta/data/patch_set.h"
#include "pumeta/geometry/sampling.h"
#include "support/test_util.h"

namespace pumeta {
namespace {

/// Three clouds of different sizes with five seeds each (GT patches of 32 points).
PatchSet small_set() {
    PatchSet set;
    set.ratio = 2;
    set.patch_points = 16;
    set.points = uniform_random_points(40 + 60 + 35, 5);
    set.offsets = at::tensor({int64_t{0}, int64_t{40}, int64_t{100}, int64_t{135}});
    std::vector<int64_t> seeds;
    for (int64_t mesh = 0; mesh < 3; ++mesh)
        for (int64_t i = 0; i < 5; ++i) seeds.insert(seeds.end(), {mesh, i * 4});
    set.seeds = at::tensor(seeds).view({15, 2});
    set.ids = {"a", "b", "c"};
    return set;
}

TEST(DistributedSampler, ShardsTogetherAreTheUnshardedBatch) {
    PatchSet set = small_set();
    for (InputSampler sampler :
         {InputSampler::kFps, InputSampler::kRandom, InputSampler::kNonuniform})
        for (bool augment : {false, true})
            for (int64_t world : {2, 4}) {
                LoaderOptions options;
                options.batch_size = 4;  // 3 batches per epoch: 7 batches cross two epochs
                options.sampler = sampler;
                options.augment = augment;
                options.seed = 11;
                PatchLoader whole(set, options);
                std::vector<PatchLoader> shards;
                for (int64_t rank = 0; rank < world; ++rank) {
                    LoaderOptions sharded = options;
                    sharded.shard_index = rank;
                    sharded.shard_count = world;
                    shards.emplace_back(set, sharded);
                }
                for (int batch = 0; batch < 7; ++batch) {
                    Batch expected = whole.next();
                    std::vector<at::Tensor> inputs, gts;
                    for (PatchLoader& shard : shards) {
                        Batch part = shard.next();
                        ASSERT_EQ(part.input.size(0), options.batch_size / world);
                        inputs.push_back(part.input);
                        gts.push_back(part.gt);
                    }
                    std::string where = to_string(sampler) + (augment ? " augmented" : "") +
                                        " W=" + std::to_string(world) + " batch " +
                                        std::to_string(batch);
                    EXPECT_TRUE(at::cat(inputs).equal(expected.input)) << where;
                    EXPECT_TRUE(at::cat(gts).equal(expected.gt)) << where;
                }
            }
}

TEST(DistributedSampler, ShardedLoaderResumesAtAPosition) {
    PatchSet set = small_set();
    LoaderOptions options;
    options.batch_size = 4;
    options.seed = 3;
    options.shard_index = 1;
    options.shard_count = 2;
    PatchLoader straight(set, options);
    for (int i = 0; i < 4; ++i) straight.next();
    PatchLoader resumed(set, options);
    resumed.seek(4);
    Batch a = straight.next(), b = resumed.next();
    EXPECT_TRUE(a.input.equal(b.input));
    EXPECT_TRUE(a.gt.equal(b.gt));
}

TEST(DistributedSampler, RejectsShardsThatDoNotSplitTheBatchEvenly) {
    PatchSet set = small_set();
    LoaderOptions options;
    options.batch_size = 4;
    options.shard_count = 3;
    EXPECT_THROW(PatchLoader(set, options), InputError);
    options.shard_count = 2;
    options.shard_index = 2;
    EXPECT_THROW(PatchLoader(set, options), InputError);
}

}  // namespace
}  // namespace pumeta
