#pragma once
// Items bucketed by band of image rows, so that each band is drawn by exactly one task, with no
// locks: the far blit and the CPU reference both lay their sprites out this way.
#include <cstddef>
#include <cstdint>
#include <utility>
#include <vector>

namespace voxtier {

/// Band b holds list[start[b] .. start[b + 1]), the items meeting its rows, in item order.
struct RowBands {
    std::vector<std::uint32_t> start, list;
};

/// Buckets items 0 .. count-1 into `bands` bands of `bandRows` rows by a counting sort, keeping
/// item order within a band. rowsOf(i) is the half-open range of image rows item i covers (within
/// the image; an empty range puts it in no band).
template <class RowsOf>
RowBands bucketByBand(std::size_t count, int bands, int bandRows, RowsOf&& rowsOf) {
    RowBands out;
    out.start.assign(std::size_t(bands) + 1, 0);
    const auto bandsOf = [&](std::size_t i) {
        const std::pair<int, int> rows = rowsOf(i);
        if (rows.first >= rows.second) return std::pair<int, int>{0, 0};
        return std::pair<int, int>{rows.first / bandRows, (rows.second - 1) / bandRows + 1};
    };
    for (std::size_t i = 0; i < count; ++i) {
        const auto [first, last] = bandsOf(i);
        for (int b = first; b < last; ++b) ++out.start[std::size_t(b) + 1];
    }
    for (std::size_t b = 0; b < std::size_t(bands); ++b) out.start[b + 1] += out.start[b];
    out.list.resize(out.start.back());
    std::vector<std::uint32_t> fill(out.start.begin(), out.start.end() - 1);
    for (std::size_t i = 0; i < count; ++i) {
        const auto [first, last] = bandsOf(i);
        for (int b = first; b < last; ++b) out.list[fill[std::size_t(b)]++] = std::uint32_t(i);
    }
    return out;
}

} // namespace voxtier
