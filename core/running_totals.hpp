#pragma once
// Running totals of per-item counts, over the cores where there are enough of them: where each
// item's entries start in a list built in parallel (the near tier's work lists, the cell-rate
// plan's cell store). On the H200's 16-core host one core summing 84,000 sprites' counts took
// 0.27 ms a pass (run 14), and the near lists' serial passes ~1 ms of their 1.5; on this project's
// 2-core machine the same passes take 0.07 ms, and a parallel form 0.2 (its tasks' start-up).
#include <cstddef>
#include <cstdint>
#include <functional>
#include <span>
#include <vector>

namespace voxtier {

/// Items per task of the chunked parallel passes: a few dozen tasks at 100,000 items.
inline constexpr std::size_t kRunningTotalsChunk = 4096;
/// Whether a pass over `items` goes over the cores: at least two chunks, and at least 4 threads
/// in the calling arena (below, one core's pass is faster).
bool runningTotalsInParallel(std::size_t items);
/// The chunks `items` are cut into, kRunningTotalsChunk each (the last one shorter).
inline std::size_t chunkCount(std::size_t items) {
    return (items + kRunningTotalsChunk - 1) / kRunningTotalsChunk;
}
/// f(chunk, first, end) for each chunk of `items`, over the cores: items [first, end) are the
/// chunk's. The one walk over the chunks of every chunked pass (a few dozen calls, so the
/// std::function costs nothing against a chunk's 4,096 items).
void forEachChunk(
    std::size_t items,
    const std::function<void(std::size_t chunk, std::size_t first, std::size_t end)>& f);

/// In place: on entry starts[k + 1] holds item k's count (starts[0] is not read), on return
/// starts[k] is the sum of the counts of the items before k, and starts.back() the sum of all:
/// the same integers either way. `chunkSums` is scratch the caller keeps.
void runningTotals(std::span<std::uint64_t> starts, std::vector<std::uint64_t>& chunkSums);

} // namespace voxtier
