// sortKeyIndexPairs: the draw orders' radix sort gives std::sort's order of the pairs, for the
// inputs the frames give it (depth-and-id keys with ascending indices) and for any other.
#include "core/key_sort.hpp"

#include <gtest/gtest.h>
#include <tbb/blocked_range.h>
#include <tbb/parallel_reduce.h>
#include <tbb/task_arena.h>

#include <algorithm>
#include <cstdint>
#include <numeric>
#include <random>
#include <vector>

namespace voxtier {
namespace {

// The sort under test on a copy, against std::sort on another: the same pairs in the same order.
void expectSortedAsStdSort(const std::vector<KeyIndex>& input, KeyIndexScratch& scratch,
                           const char* what) {
    std::vector<KeyIndex> expected = input, got = input;
    std::sort(expected.begin(), expected.end());
    sortKeyIndexPairs(got, scratch);
    ASSERT_EQ(got.size(), expected.size()) << what;
    const auto differ = std::mismatch(got.begin(), got.end(), expected.begin());
    EXPECT_TRUE(differ.first == got.end())
        << what << ", " << input.size() << " pairs: first difference at "
        << (differ.first - got.begin());
}

// Sizes around the comparison sort's limit and the chunk's, and the frames' 100,000.
const std::size_t kSizes[] = {0,    1,     2,     3,     100,   4095,  4096,
                              4097, 16383, 16384, 16385, 50000, 100000};

TEST(KeyIndexSort, EqualsStdSortOnDepthAndIdKeysWithAscendingIndices) {
    // frontToBack's keys: a float depth's bits inverted over an entity id; the far pass's
    // ordered depth likewise. Depths within a narrow range share their high bits.
    std::mt19937_64 rng(7);
    KeyIndexScratch scratch;
    for (const std::size_t n : kSizes) {
        std::vector<KeyIndex> pairs(n);
        std::uniform_real_distribution<float> depth(1e-4f, 2e-3f);
        for (std::uint32_t i = 0; i < n; ++i) {
            const std::uint32_t bits = std::bit_cast<std::uint32_t>(depth(rng));
            const std::uint32_t entity = std::uint32_t(rng() % (n + 1)) * 3;
            pairs[i] = {(std::uint64_t(~bits) << 32) | entity, i};
        }
        expectSortedAsStdSort(pairs, scratch, "depth and id");
    }
}

TEST(KeyIndexSort, TieBreakingBitsThatFollowTheIndexNeedNoPassYetGiveStdSortsOrder) {
    // frontToBack's keys when the sprites come in entity order: the id in the low half ascends
    // with the index, so tieBits = 32 may spare the id's digits. Many equal depths, so the ids
    // decide often; the answer must be std::sort's. With the same pairs' indices shuffled (the
    // id no longer follows the index), the sort must not spare them.
    std::mt19937_64 rng(19);
    KeyIndexScratch scratch;
    for (const std::size_t n : kSizes) {
        std::vector<KeyIndex> pairs(n);
        std::uint32_t entity = 0;
        for (std::uint32_t i = 0; i < n; ++i) {
            entity += 1 + std::uint32_t(rng() % 3); // ascending, with gaps
            const std::uint32_t bits = std::bit_cast<std::uint32_t>(float(rng() % 64) / 64.0f);
            pairs[i] = {(std::uint64_t(~bits) << 32) | entity, i};
        }
        std::vector<KeyIndex> expected = pairs, got = pairs;
        std::sort(expected.begin(), expected.end());
        sortKeyIndexPairs(got, scratch, 32);
        EXPECT_TRUE(got == expected) << n << " pairs, ids ascending with the index";
        std::vector<std::uint32_t> index(n);
        std::iota(index.begin(), index.end(), 0u);
        std::shuffle(index.begin(), index.end(), rng);
        for (std::size_t i = 0; i < n; ++i) pairs[i].second = index[i];
        expected = pairs, got = pairs;
        std::sort(expected.begin(), expected.end());
        sortKeyIndexPairs(got, scratch, 32);
        EXPECT_TRUE(got == expected) << n << " pairs, indices shuffled";
    }
}

TEST(KeyIndexSort, AscendingIdsGatheredInParallelAgreeWithOneWalk) {
    // The callers' test for tieBits: strictly ascending ids, equal neighbours, one id out of
    // place at each position class (first, inside, at a range border, last), and none at all.
    std::mt19937_64 rng(23);
    const auto walk = [](const std::vector<std::uint32_t>& ids) {
        for (std::size_t i = 1; i < ids.size(); ++i)
            if (!(ids[i - 1] < ids[i])) return false;
        return true;
    };
    const auto gathered = [](const std::vector<std::uint32_t>& ids) {
        return tbb::parallel_reduce(
                   tbb::blocked_range<std::size_t>(0, ids.size(), 64), AscendingIds{},
                   [&](const auto& r, AscendingIds seen) {
                       for (std::size_t i = r.begin(); i != r.end(); ++i) seen.add(ids[i]);
                       return seen;
                   },
                   AscendingIds::join)
            .ascending;
    };
    for (const std::size_t n : {0u, 1u, 2u, 63u, 64u, 65u, 4096u, 100000u}) {
        std::vector<std::uint32_t> ids(n);
        std::uint32_t id = 0;
        for (auto& x : ids) x = id += 1 + std::uint32_t(rng() % 4);
        EXPECT_TRUE(gathered(ids)) << n;
        for (const std::size_t at : {std::size_t(1), n / 2, std::size_t(64), n - 1}) {
            if (at == 0 || at >= n) continue;
            std::vector<std::uint32_t> bent = ids;
            bent[at] = bent[at - 1]; // equal neighbours: not strictly ascending
            EXPECT_EQ(gathered(bent), walk(bent)) << n << " equal at " << at;
            bent[at] = bent[at - 1] - 1;
            EXPECT_FALSE(gathered(bent)) << n << " falling at " << at;
        }
    }
}

TEST(KeyIndexSort, EqualsStdSortWithTiesAndIndicesInAnyOrder) {
    std::mt19937_64 rng(11);
    KeyIndexScratch scratch;
    for (const std::size_t n : kSizes) {
        for (const int distinctKeys : {1, 2, 7, 300}) {
            // Few distinct keys, so most pairs tie on the key and the index decides; indices
            // shuffled, descending, or with repeats (equal pairs).
            std::vector<KeyIndex> pairs(n);
            std::vector<std::uint32_t> index(n);
            std::iota(index.begin(), index.end(), 0u);
            std::shuffle(index.begin(), index.end(), rng);
            for (std::size_t i = 0; i < n; ++i)
                pairs[i] = {(rng() % std::uint64_t(distinctKeys)) << 40, index[i]};
            expectSortedAsStdSort(pairs, scratch, "ties, shuffled indices");
            for (std::size_t i = 0; i < n; ++i) pairs[i].second = std::uint32_t(n - i) << 12;
            expectSortedAsStdSort(pairs, scratch, "ties, descending indices");
            for (std::size_t i = 0; i < n; ++i) pairs[i].second = std::uint32_t(rng() % 5);
            expectSortedAsStdSort(pairs, scratch, "ties, repeated indices");
        }
    }
}

TEST(KeyIndexSort, EqualsStdSortOnKeysThatDifferInAnyByte) {
    // Every digit of the key and of the index in turn the only one that varies (a pass each, the
    // others spared), then all of them (every pass).
    std::mt19937_64 rng(13);
    KeyIndexScratch scratch;
    const std::size_t n = 40000;
    for (int shift = 0; shift < 64; shift += 8) {
        std::vector<KeyIndex> pairs(n);
        for (std::uint32_t i = 0; i < n; ++i)
            pairs[i] = {0x0123456789ABCDEFull ^ ((rng() & 0xFF) << shift), i};
        expectSortedAsStdSort(pairs, scratch, "one key byte varies");
        std::reverse(pairs.begin(), pairs.end());
        expectSortedAsStdSort(pairs, scratch, "one key byte varies, indices descending");
    }
    for (int shift = 0; shift < 32; shift += 8) {
        std::vector<KeyIndex> pairs(n);
        for (std::uint32_t i = 0; i < n; ++i)
            pairs[i] = {42, 0x01234567u ^ std::uint32_t((rng() & 0xFF) << shift)};
        expectSortedAsStdSort(pairs, scratch, "one index byte varies");
    }
    std::vector<KeyIndex> pairs(n);
    for (auto& p : pairs) p = {rng(), std::uint32_t(rng())};
    expectSortedAsStdSort(pairs, scratch, "every bit random");
    // Already sorted, and sorted backwards.
    std::sort(pairs.begin(), pairs.end());
    expectSortedAsStdSort(pairs, scratch, "sorted");
    std::reverse(pairs.begin(), pairs.end());
    expectSortedAsStdSort(pairs, scratch, "reversed");
}

TEST(KeyIndexSort, EqualsStdSortWhateverTheThreadCount) {
    // The pairs are cut into chunks by the threads at hand (about four a thread, 2,048 to
    // 16,384 pairs each): one thread, two, and sixteen (more chunks than this host has cores).
    std::mt19937_64 rng(29);
    KeyIndexScratch scratch;
    for (const int threads : {1, 2, 16}) {
        tbb::task_arena arena(threads);
        for (const std::size_t n : {4097u, 30000u, 100000u}) {
            std::vector<KeyIndex> pairs(n);
            for (std::uint32_t i = 0; i < n; ++i) pairs[i] = {rng() >> 40, i};
            arena.execute([&] { expectSortedAsStdSort(pairs, scratch, "threads"); });
            std::reverse(pairs.begin(), pairs.end());
            arena.execute([&] { expectSortedAsStdSort(pairs, scratch, "threads, reversed"); });
        }
    }
}

TEST(KeyIndexSort, ScratchKeptBetweenSortsOfOtherSizes) {
    // A frame's sort reuses the last frame's scratch, larger or smaller than it needs.
    std::mt19937_64 rng(17);
    KeyIndexScratch scratch;
    for (const std::size_t n : {100000u, 5000u, 70000u, 4096u, 100001u}) {
        std::vector<KeyIndex> pairs(n);
        for (std::uint32_t i = 0; i < n; ++i) pairs[i] = {rng() >> 20, i};
        expectSortedAsStdSort(pairs, scratch, "scratch reused");
    }
}

} // namespace
} // namespace voxtier
