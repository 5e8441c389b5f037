#pragma once
// Internal to impostor_cache (not installed): what the far blit's two kernels share. blitFar
// (far_blit.cpp) gathers each far sprite's constants once per frame, buckets the sprites by
// band of image rows, and hands each band to one task; the band kernel is either the scalar
// reference (far_blit.cpp) or the vectorised one (far_blit_simd.cpp), which must write the same
// bits.
#include "core/image.hpp"
#include "core/occlusion.hpp"
#include "core/sprite_kernel.h"
#include "impostor_cache/far_blit.hpp"
#include "impostor_cache/snapshot.hpp"

#include <algorithm>
#include <array>
#include <cstddef>
#include <cstdint>
#include <utility>

namespace voxtier::detail {

/// One far sprite, as both kernels read it.
struct BlitSprite {
    const kernel::SpriteGpu* gpu = nullptr;
    const Snapshot* snapshot = nullptr;
    const Rgba8* palette = nullptr; ///< 256 colours
    SnapshotCellMap map;            ///< near cell -> snapshot cell
    glm::ivec4 rect{0};             ///< screen rectangle x0, y0, x1, y1 (half-open)
    std::uint32_t entity = 0;
    /// kernel::vtFaceLight by snapshot code: [kSolid0 + f] is face f's factor, the rest 0. A
    /// table lookup by code is what lets the SIMD kernel light 16 pixels without a branch.
    std::array<std::uint32_t, 8> lightByCode{};
};

struct BlitCounters {
    std::uint64_t tested = 0, written = 0;
    std::uint64_t partsCulled = 0; ///< (sprite, tile row) parts the occlusion tiles hid
};

/// Rows [y0, y1) of the target, drawn by one task: the sprites `list[0 .. count)` (indices into
/// `sprites`) are those whose rectangle meets the band.
struct BlitBand {
    const BlitSprite* sprites = nullptr;
    const std::uint32_t* list = nullptr;
    std::size_t count = 0;
    int y0 = 0, y1 = 0;
    Image* target = nullptr;
    /// Occlusion culling (null: none). The band's rows are whole tile rows of these tiles, which
    /// no other task reads or writes while the band is drawn.
    OcclusionTiles* tiles = nullptr;
};

/// Calls draw(part, y0, y1) for sprite `s`'s rows in the band, one tile row at a time, with the
/// part's rectangle cut to the columns the band's occlusion tiles leave open (all of them without
/// tiles). Both kernels draw through this, so they cull alike.
template <class Draw>
void drawInBand(const BlitBand& band, const BlitSprite& s, BlitCounters& counters, Draw&& draw) {
    const int y0 = std::max(s.rect.y, band.y0), y1 = std::min(s.rect.w, band.y1);
    if (!band.tiles) {
        draw(s, y0, y1);
        return;
    }
    constexpr int kTile = OcclusionTiles::kTile;
    for (int y = y0; y < y1;) {
        const int row = y / kTile, end = std::min(y1, (row + 1) * kTile);
        const auto [x0, x1] = band.tiles->visibleColumns(row, s.rect.x, s.rect.z, s.gpu->depth);
        if (x0 < x1) {
            BlitSprite part = s;
            part.rect.x = x0;
            part.rect.z = x1;
            draw(part, y, end);
            band.tiles->drawn(row, x0, x1, end - y);
        } else {
            ++counters.partsCulled;
        }
        y = end;
    }
}

/// The columns [x0, x1) of pixel row `py` (pixel centre y) outside which vtPixelCell cannot find
/// a cell of the sprite (far_blit.cpp). Both kernels test exactly these pixels.
std::pair<int, int> candidateColumns(const kernel::SpriteGpu& g, double py, int rx0, int rx1);

/// The reference: per pixel, kernel::vtPixelCell, SnapshotCellMap, vtLit and writeIfNearer.
void blitBandScalar(const BlitBand& band, BlitCounters& counters);
/// One sprite's rows [y0, y1) by the reference (what the SIMD kernel falls back to for the cases
/// it does not vectorise: images narrower than a vector, snapshots of under two cells).
void blitSpriteScalar(const BlitSprite& sprite, int y0, int y1, Image& target,
                      BlitCounters& counters);
/// The vectorised kernel on the best SIMD target of this CPU (Highway dynamic dispatch).
void blitBandSimd(const BlitBand& band, BlitCounters& counters);

} // namespace voxtier::detail
