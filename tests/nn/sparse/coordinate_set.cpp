// Coordinate hashing, coarser and generated sets, and kernel maps against brute force; the
// kernel-map cache.
#include "pumeta/nn/sparse/coordinate_set.h"

#include <ATen/ATen.h>
#include <gtest/gtest.h>

#include <array>
#include <map>
#include <random>
#include <set>

#include "pumeta/core/error.h"
#include "pumeta/nn/sparse/coordinate_hash.h"

namespace pumeta {
namespace {

using Site = std::array<int64_t, 4>;

/// Distinct random sites in [lo, lo + extent)^3 for `batches` elements, multiples of stride.
at::Tensor random_sites(int64_t count, int64_t batches, int64_t lo, int64_t extent, int64_t stride,
                        uint64_t seed) {
    std::mt19937_64 rng(seed);
    std::set<Site> seen;
    std::vector<int32_t> flat;
    while (int64_t(seen.size()) < count) {
        Site s{int64_t(rng() % batches), lo + int64_t(rng() % extent) * stride,
               lo + int64_t(rng() % extent) * stride, lo + int64_t(rng() % extent) * stride};
        if (seen.insert(s).second)
            for (int64_t v : s) flat.push_back(int32_t(v));
    }
    at::Tensor t = at::empty({count, 4}, at::kInt);
    std::copy(flat.begin(), flat.end(), t.data_ptr<int32_t>());
    return t;
}

std::map<Site, int64_t> rows_of(const CoordinateSet& set) {
    std::map<Site, int64_t> rows;
    at::Tensor c = set.coords().to(at::kLong);
    for (int64_t i = 0; i < set.size(); ++i)
        rows[{c[i][0].item<int64_t>(), c[i][1].item<int64_t>(), c[i][2].item<int64_t>(),
              c[i][3].item<int64_t>()}] = i;
    return rows;
}

/// The pairs of one offset of a map as a set of (in, out).
std::set<std::pair<int64_t, int64_t>> pairs(const KernelMap& map, int64_t k) {
    std::set<std::pair<int64_t, int64_t>> result;
    for (int64_t i = 0; i < map.in[k].numel(); ++i)
        result.insert({map.in[k][i].item<int64_t>(), map.out[k][i].item<int64_t>()});
    return result;
}

int64_t floor_div_oracle(int64_t a, int64_t b) {
    return int64_t(std::floor(double(a) / double(b)));
}

TEST(CoordinateHash, FindsEveryInsertedKeyAndNothingElseAcrossGrowth) {
    std::mt19937_64 rng(1);
    std::map<uint64_t, int64_t> oracle;
    CoordinateHash hash(4);  // grows many times
    for (int64_t i = 0; i < 5000; ++i) {
        uint64_t key = pack_coordinate(rng() % 3, int64_t(rng() % 200) - 100,
                                       int64_t(rng() % 200) - 100, int64_t(rng() % 200) - 100);
        int64_t stored = hash.insert(key, i);
        auto [it, fresh] = oracle.emplace(key, i);
        EXPECT_EQ(stored, it->second);
    }
    EXPECT_EQ(hash.size(), int64_t(oracle.size()));
    for (const auto& [key, row] : oracle) EXPECT_EQ(hash.find(key), row);
    EXPECT_EQ(hash.find(pack_coordinate(3, 0, 0, 0)), -1);
    EXPECT_EQ(hash.find(pack_coordinate(0, 150, 0, 0)), -1);
}

TEST(CoordinateHash, PackingIsInjectiveAtTheRangeLimits) {
    std::set<uint64_t> keys;
    for (int64_t b : {int64_t(0), kMaxBatch})
        for (int64_t x : {kMinCoordinate, int64_t(-1), int64_t(0), kMaxCoordinate})
            for (int64_t y : {kMinCoordinate, kMaxCoordinate})
                for (int64_t z : {kMinCoordinate, int64_t(0), kMaxCoordinate})
                    keys.insert(pack_coordinate(b, x, y, z));
    EXPECT_EQ(keys.size(), 2u * 4 * 2 * 3);
    EXPECT_FALSE(packable(0, kMaxCoordinate + 1, 0, 0));
    EXPECT_FALSE(packable(kMaxBatch + 1, 0, 0, 0));
}

TEST(CoordinateSet, RejectsDuplicatesOffStrideAndOutOfRangeSites) {
    at::Tensor dup = at::tensor({0, 1, 2, 3, 0, 1, 2, 3}, at::kInt).view({2, 4});
    EXPECT_THROW(CoordinateSet::create(dup, 1), InputError);
    at::Tensor odd = at::tensor({0, 2, 4, 5}, at::kInt).view({1, 4});
    EXPECT_THROW(CoordinateSet::create(odd, 2), InputError);
    at::Tensor far = at::tensor({0, 40000, 0, 0}, at::kLong).view({1, 4});
    EXPECT_THROW(CoordinateSet::create(far, 1), InputError);
    EXPECT_THROW(CoordinateSet::create(at::zeros({3, 3}, at::kInt), 1), InputError);
}

TEST(CoordinateSet, LookupMatchesBruteForce) {
    auto set = CoordinateSet::create(random_sites(300, 2, -5, 10, 1, 2), 1);
    std::map<Site, int64_t> rows = rows_of(*set);
    at::Tensor queries = random_sites(200, 3, -6, 12, 1, 3);
    at::Tensor found = set->lookup(queries);
    for (int64_t i = 0; i < queries.size(0); ++i) {
        Site s{queries[i][0].item<int64_t>(), queries[i][1].item<int64_t>(),
               queries[i][2].item<int64_t>(), queries[i][3].item<int64_t>()};
        auto it = rows.find(s);
        EXPECT_EQ(found[i].item<int64_t>(), it == rows.end() ? -1 : it->second);
    }
}

TEST(CoordinateSet, CoarserFloorsToMultiplesIncludingNegativeCoordinates) {
    at::Tensor sites = random_sites(400, 2, -9, 18, 1, 4);
    auto fine = CoordinateSet::create(sites, 1);
    auto coarse = fine->coarser(2);
    EXPECT_EQ(coarse->stride(), 2);
    std::set<Site> expected;
    for (int64_t i = 0; i < sites.size(0); ++i) {
        Site s{sites[i][0].item<int64_t>(), 0, 0, 0};
        for (int a = 1; a < 4; ++a) s[a] = floor_div_oracle(sites[i][a].item<int64_t>(), 2) * 2;
        expected.insert(s);
    }
    std::map<Site, int64_t> rows = rows_of(*coarse);
    EXPECT_EQ(rows.size(), expected.size());
    for (const Site& s : expected) EXPECT_TRUE(rows.count(s));
    // Cached: the same object, whose own coarser set is at stride 4.
    EXPECT_EQ(fine->coarser(2), coarse);
    EXPECT_EQ(coarse->coarser(2)->stride(), 4);
}

TEST(CoordinateSet, ConvMapMatchesBruteForceWithDilationAndStride) {
    // A stride-2 set with dilation 2: taps at offset·2·2.
    auto set = CoordinateSet::create(random_sites(250, 2, -4, 8, 2, 5), 2);
    auto map = set->conv_map(3, 2);
    std::map<Site, int64_t> rows = rows_of(*set);
    auto offsets = kernel_offsets(3);
    ASSERT_EQ(map->kernel_volume(), 27);
    for (int64_t k = 0; k < 27; ++k) {
        std::set<std::pair<int64_t, int64_t>> expected;
        for (const auto& [site, out] : rows) {
            Site q = site;
            for (int a = 0; a < 3; ++a) q[a + 1] += offsets[k][a] * 4;
            auto it = rows.find(q);
            if (it != rows.end()) expected.insert({it->second, out});
        }
        EXPECT_EQ(pairs(*map, k), expected) << "offset " << k;
    }
    EXPECT_EQ(map->identity_offset, 13);
    EXPECT_EQ(map->in[13].numel(), set->size());
}

TEST(CoordinateSet, DownMapReadsFineSitesAroundEachCoarseSite) {
    auto fine = CoordinateSet::create(random_sites(300, 2, -5, 10, 1, 6), 1);
    auto coarse = fine->coarser(2);
    auto map = fine->down_map(3, 2);
    EXPECT_EQ(map->input_size, fine->size());
    EXPECT_EQ(map->output_size, coarse->size());
    std::map<Site, int64_t> fine_rows = rows_of(*fine), coarse_rows = rows_of(*coarse);
    auto offsets = kernel_offsets(3);
    for (int64_t k = 0; k < 27; ++k) {
        std::set<std::pair<int64_t, int64_t>> expected;
        for (const auto& [site, out] : coarse_rows) {
            Site q = site;
            for (int a = 0; a < 3; ++a) q[a + 1] += offsets[k][a];
            auto it = fine_rows.find(q);
            if (it != fine_rows.end()) expected.insert({it->second, out});
        }
        EXPECT_EQ(pairs(*map, k), expected) << "offset " << k;
    }
}

TEST(CoordinateSet, GeneratedSitesAreEveryKernelReachOfEveryCoarseSite) {
    auto coarse = CoordinateSet::create(random_sites(40, 2, -6, 6, 2, 7), 2);
    auto generated = coarse->generated(5, 2);
    EXPECT_EQ(generated.set->stride(), 1);
    std::map<Site, int64_t> coarse_rows = rows_of(*coarse), new_rows = rows_of(*generated.set);
    std::set<Site> expected;
    auto offsets = kernel_offsets(5);
    for (int64_t k = 0; k < 125; ++k) {
        std::set<std::pair<int64_t, int64_t>> expected_pairs;
        for (const auto& [site, in] : coarse_rows) {
            Site q = site;
            for (int a = 0; a < 3; ++a) q[a + 1] += offsets[k][a];
            expected.insert(q);
            ASSERT_TRUE(new_rows.count(q));
            expected_pairs.insert({in, new_rows.at(q)});
        }
        EXPECT_EQ(pairs(*generated.map, k), expected_pairs);
    }
    EXPECT_EQ(new_rows.size(), expected.size());
    EXPECT_THROW(generated.set->generated(3, 2), InputError);  // stride 1 cannot halve
}

TEST(CoordinateSet, KernelMapsAreBuiltOncePerSetAndShared) {
    auto set = CoordinateSet::create(random_sites(200, 1, 0, 8, 1, 8), 1);
    EXPECT_EQ(set->kernel_maps_built(), 0);
    auto first = set->conv_map(3, 1);
    auto again = set->conv_map(3, 1);
    EXPECT_EQ(first.get(), again.get());
    EXPECT_EQ(first->in[0].data_ptr(), again->in[0].data_ptr());
    EXPECT_EQ(set->kernel_maps_built(), 1);
    set->conv_map(3, 2);
    set->conv_map(5, 1);
    set->down_map(3, 2);
    set->down_map(3, 2);
    set->generated(3, 1);
    set->generated(3, 1);
    EXPECT_EQ(set->kernel_maps_built(), 5);
}

}  // namespace
}  // namespace pumeta
