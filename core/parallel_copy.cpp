#include "core/parallel_copy.hpp"

#include <tbb/parallel_for.h>

#include <algorithm>
#include <cstdint>
#include <cstring>
#include <vector>

namespace voxtier {

void copyInParallel(std::span<const CopyPiece> pieces) {
    constexpr std::size_t kChunk = std::size_t(256) << 10;
    // Each piece's first chunk among all the pieces' chunks.
    std::vector<std::size_t> firstChunk(pieces.size() + 1, 0);
    for (std::size_t p = 0; p < pieces.size(); ++p)
        firstChunk[p + 1] = firstChunk[p] + (pieces[p].bytes + kChunk - 1) / kChunk;
    const std::size_t chunks = firstChunk.back();
    if (chunks == 1) { // one small copy: no task to hand out
        for (const CopyPiece& p : pieces)
            if (p.bytes) std::memcpy(p.to, p.from, p.bytes);
        return;
    }
    tbb::parallel_for(std::size_t(0), chunks, [&](std::size_t k) {
        const std::size_t p =
            std::size_t(std::upper_bound(firstChunk.begin(), firstChunk.end(), k) -
                        firstChunk.begin()) -
            1;
        const CopyPiece& piece = pieces[p];
        const std::size_t offset = (k - firstChunk[p]) * kChunk;
        std::memcpy(static_cast<std::uint8_t*>(piece.to) + offset,
                    static_cast<const std::uint8_t*>(piece.from) + offset,
                    std::min(kChunk, piece.bytes - offset));
    });
}

} // namespace voxtier
