#include "core/running_totals.hpp"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include <algorithm>

namespace voxtier {

bool runningTotalsInParallel(std::size_t items) {
    return items >= 2 * kRunningTotalsChunk && tbb::this_task_arena::max_concurrency() >= 4;
}

void forEachChunk(
    std::size_t items,
    const std::function<void(std::size_t chunk, std::size_t first, std::size_t end)>& f) {
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, chunkCount(items), 1), [&](const auto& r) {
        for (std::size_t c = r.begin(); c != r.end(); ++c)
            f(c, c * kRunningTotalsChunk, std::min(items, (c + 1) * kRunningTotalsChunk));
    });
}

void runningTotals(std::span<std::uint64_t> starts, std::vector<std::uint64_t>& chunkSums) {
    if (starts.empty()) return;
    starts[0] = 0;
    const std::size_t n = starts.size() - 1; // items
    if (!runningTotalsInParallel(n)) {
        for (std::size_t k = 0; k < n; ++k) starts[k + 1] += starts[k];
        return;
    }
    // Each chunk's sum, then the chunks' running totals (a few dozen, serial), then each chunk's
    // items from its start.
    chunkSums.resize(chunkCount(n));
    forEachChunk(n, [&](std::size_t c, std::size_t first, std::size_t end) {
        std::uint64_t sum = 0;
        for (std::size_t k = first; k != end; ++k) sum += starts[k + 1];
        chunkSums[c] = sum;
    });
    std::uint64_t total = 0;
    for (std::uint64_t& s : chunkSums) {
        const std::uint64_t chunk = s;
        s = total;
        total += chunk;
    }
    forEachChunk(n, [&](std::size_t c, std::size_t first, std::size_t end) {
        std::uint64_t running = chunkSums[c];
        for (std::size_t k = first; k != end; ++k) starts[k + 1] = running += starts[k + 1];
    });
}

} // namespace voxtier
