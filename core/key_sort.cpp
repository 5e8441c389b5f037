#include "core/key_sort.hpp"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/parallel_reduce.h>
#include <tbb/task_arena.h>

#include <algorithm>
#include <array>

namespace voxtier {

namespace {

constexpr int kDigitBits = 8;
constexpr std::size_t kBuckets = std::size_t(1) << kDigitBits;
static_assert(std::tuple_size_v<KeyIndexScratch::Buckets> == kBuckets);
/// Below this a comparison sort is as fast, and one thread does it.
constexpr std::size_t kRadixFrom = 4096;
/// Pairs a chunk, at most and at least: each chunk counts and scatters its own part of a pass, so
/// that the parallel passes stay stable (chunk c's pairs of a bucket go before chunk c+1's). A
/// sort cuts its pairs into about four chunks a thread within these bounds: at the largest size
/// 100,000 sprites were 7 chunks, which left 9 of the H200 host's 16 cores idle in each pass.
constexpr std::size_t kMaxChunk = 16384, kMinChunk = 2048;

/// What a parallel scan of the input tells: the bits every key has (and), the bits some key has
/// (or), the same of the indices, and whether the indices ascend.
struct Shared {
    std::uint64_t keyAnd = ~std::uint64_t(0), keyOr = 0;
    std::uint32_t indexAnd = ~std::uint32_t(0), indexOr = 0;
    bool ascending = true;
};

/// The value a pass sorts by: digit `d` of the 96-bit (key, index) number, index digits first.
struct Digit {
    bool ofKey = false;
    int shift = 0;
    std::size_t of(const KeyIndex& p) const {
        return std::size_t((ofKey ? p.first : std::uint64_t(p.second)) >> shift) & (kBuckets - 1);
    }
};

} // namespace

void sortKeyIndexPairs(std::vector<KeyIndex>& pairs, KeyIndexScratch& scratch, int tieBits) {
    const std::size_t n = pairs.size();
    if (n < kRadixFrom) {
        std::sort(pairs.begin(), pairs.end());
        return;
    }
    const std::size_t threads = std::size_t(tbb::this_task_arena::max_concurrency());
    const std::size_t chunk = std::clamp(n / (4 * threads), kMinChunk, kMaxChunk);
    const std::size_t chunks = (n + chunk - 1) / chunk;
    const Shared shared = tbb::parallel_reduce(
        tbb::blocked_range<std::size_t>(0, n, chunk), Shared{},
        [&](const tbb::blocked_range<std::size_t>& r, Shared s) {
            for (std::size_t i = r.begin(); i != r.end(); ++i) {
                s.keyAnd &= pairs[i].first;
                s.keyOr |= pairs[i].first;
                s.indexAnd &= pairs[i].second;
                s.indexOr |= pairs[i].second;
                if (i > 0 && pairs[i - 1].second > pairs[i].second) s.ascending = false;
            }
            return s;
        },
        [](Shared a, const Shared& b) {
            a.keyAnd &= b.keyAnd;
            a.keyOr |= b.keyOr;
            a.indexAnd &= b.indexAnd;
            a.indexOr |= b.indexOr;
            a.ascending = a.ascending && b.ascending;
            return a;
        });
    // The passes, least significant digit first; a digit every pair shares leaves the order as it
    // is. Ascending indices are already in their final order among equal keys (the key passes are
    // stable), so their digits need no pass either.
    // At most 12 passes: 4 digits of the index, 8 of the key.
    std::array<Digit, 12> digits;
    std::size_t passes = 0;
    const auto varies = [](std::uint64_t all, std::uint64_t any, int shift) {
        return ((all ^ any) >> shift & (kBuckets - 1)) != 0;
    };
    if (!shared.ascending)
        for (int shift = 0; shift < 32; shift += kDigitBits)
            if (varies(shared.indexAnd, shared.indexOr, shift)) digits[passes++] = {false, shift};
    // Tie-breaking digits follow the index, which is already in order when it ascends.
    const int keyFrom = shared.ascending ? tieBits : 0;
    for (int shift = keyFrom; shift < 64; shift += kDigitBits)
        if (varies(shared.keyAnd, shared.keyOr, shift)) digits[passes++] = {true, shift};
    if (passes == 0) return; // every pair equal

    scratch.pairs.resize(n);
    std::vector<KeyIndex>* from = &pairs;
    std::vector<KeyIndex>* to = &scratch.pairs;
    std::vector<std::array<std::size_t, kBuckets>>& at = scratch.buckets;
    at.resize(chunks);
    for (std::size_t pass = 0; pass < passes; ++pass) {
        const Digit digit = digits[pass];
        const std::vector<KeyIndex>& src = *from;
        std::vector<KeyIndex>& dst = *to;
        tbb::parallel_for(std::size_t(0), chunks, [&](std::size_t c) {
            std::array<std::size_t, kBuckets>& count = at[c];
            count.fill(0);
            const std::size_t end = std::min(n, (c + 1) * chunk);
            for (std::size_t i = c * chunk; i != end; ++i) ++count[digit.of(src[i])];
        });
        // Bucket by bucket, chunk by chunk: the output offsets that keep each pass stable.
        std::size_t next = 0;
        for (std::size_t b = 0; b < kBuckets; ++b)
            for (std::size_t c = 0; c < chunks; ++c) {
                const std::size_t count = at[c][b];
                at[c][b] = next;
                next += count;
            }
        tbb::parallel_for(std::size_t(0), chunks, [&](std::size_t c) {
            std::array<std::size_t, kBuckets>& place = at[c];
            const std::size_t end = std::min(n, (c + 1) * chunk);
            for (std::size_t i = c * chunk; i != end; ++i) dst[place[digit.of(src[i])]++] = src[i];
        });
        std::swap(from, to);
    }
    if (from != &pairs) pairs.swap(scratch.pairs);
}

} // namespace voxtier
