#include "impostor_cache/far_blit.hpp"

#include <tbb/combinable.h>
#include <tbb/parallel_for.h>

#include <chrono>
#include <climits>

namespace voxtier {

int chooseFarView(const SpriteSetup& sprite, ViewSet set) {
    return nearestView(set, -sprite.lattice.dir);
}

namespace {
struct RowCounters {
    std::uint64_t tested = 0, written = 0;
};
} // namespace

void blitFar(std::span<const FarSprite> sprites, Image& target, FarBlitStats* stats) {
    const auto t0 = std::chrono::steady_clock::now();
    // Each row is written by exactly one task (no locks); the depth/id rule makes the result
    // independent of the order sprites are visited in.
    std::vector<std::vector<std::uint32_t>> rows(std::size_t(target.height));
    std::uint64_t drawn = 0;
    for (std::uint32_t s = 0; s < sprites.size(); ++s) {
        const FarSprite& f = sprites[s];
        if (!f.sprite || !f.snapshot || !f.palette || !f.sprite->visible()) continue;
        ++drawn;
        for (int y = f.sprite->screenRect.y; y < std::min(f.sprite->screenRect.w, target.height);
             ++y)
            rows[std::size_t(y)].push_back(s);
    }
    tbb::combinable<RowCounters> counters;
    tbb::parallel_for(
        tbb::blocked_range<int>(0, target.height, 4), [&](const tbb::blocked_range<int>& r) {
            RowCounters& rc = counters.local();
            for (int y = r.begin(); y < r.end(); ++y) {
                const float py = float(y) + 0.5f;
                for (std::uint32_t s : rows[std::size_t(y)]) {
                    const FarSprite& f = sprites[s];
                    const SpriteSetup& sp = *f.sprite;
                    const SpriteLattice& L = sp.lattice;
                    const Snapshot& snap = *f.snapshot;
                    const kernel::SpriteGpu& g = sp.gpu;
                    // What a pixel shows depends only on its near cell, and neighbouring pixels
                    // mostly share one: the last cell's outcome is reused along the row.
                    glm::ivec2 lastCell(INT_MIN, INT_MIN);
                    bool lastDrawn = false;
                    Rgba8 lastColor = 0;
                    const std::size_t rowBase = target.index(0, y);
                    for (int x = sp.screenRect.x; x < sp.screenRect.z; ++x) {
                        ++rc.tested;
                        glm::ivec2 cell;
                        if (!kernel::vtPixelCell(g, glm::vec2(float(x) + 0.5f, py), cell)) continue;
                        if (cell != lastCell) {
                            lastCell = cell;
                            // The near cell's centre, relative to the model centre (voxel space).
                            const glm::dvec3 q = (L.gU + (cell.x + 0.5) / L.sigma) * L.right +
                                                 (L.gV + (cell.y + 0.5) / L.sigma) * L.up;
                            const glm::ivec2 sc = snap.lattice.cellAt(q);
                            const SnapshotCell c = snap.at(sc.x, sc.y);
                            lastDrawn = c.code != snapshot_code::kEmpty;
                            if (lastDrawn)
                                lastColor = snapshot_code::isSolid(c.code)
                                                ? kernel::vtLit(f.palette->colors[c.index],
                                                                kernel::vtFaceLight(g, snapshot_code::face(c.code)))
                                                : kernel::VT_OUTLINE_RGBA;
                        }
                        if (!lastDrawn) continue;
                        ++rc.written;
                        target.writeIfNearer(rowBase + std::size_t(x), lastColor, g.depth, sp.entityId);
                    }
                }
            }
        });
    if (stats) {
        RowCounters total;
        counters.combine_each([&](const RowCounters& c) {
            total.tested += c.tested;
            total.written += c.written;
        });
        stats->sprites += drawn;
        stats->pixelsTested += total.tested;
        stats->pixelsWritten += total.written;
        stats->milliseconds +=
            std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0)
                .count();
    }
}

} // namespace voxtier
