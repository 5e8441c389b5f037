#include "impostor_cache/far_blit.hpp"

#include "core/stopwatch.hpp"

#include <tbb/combinable.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <chrono>
#include <climits>
#include <cmath>
#include <limits>
#include <utility>

namespace voxtier {

SnapshotCellMap snapshotCellMap(const SpriteLattice& L, const SpriteLattice& S) {
    // q(i, j) = (gU + (i + ½)/σ) R + (gV + (j + ½)/σ) U; u = σs (q·Rs − gUs), v = σs (q·Us − gVs).
    const double rr = glm::dot(L.right, S.right), ur = glm::dot(L.up, S.right);
    const double ru = glm::dot(L.right, S.up), uu = glm::dot(L.up, S.up);
    const double a = L.gU + 0.5 / L.sigma, b = L.gV + 0.5 / L.sigma, k = S.sigma / L.sigma;
    SnapshotCellMap m;
    m.u0 = S.sigma * (a * rr + b * ur - S.gU);
    m.ui = k * rr;
    m.uj = k * ur;
    m.v0 = S.sigma * (a * ru + b * uu - S.gV);
    m.vi = k * ru;
    m.vj = k * uu;
    return m;
}

int chooseFarView(const SpriteSetup& sprite, ViewSet set) {
    return nearestView(set, -sprite.lattice.dir);
}

namespace {
struct RowCounters {
    std::uint64_t tested = 0, written = 0;
};

/// The columns [x0, x1) of pixel row `py` (pixel centre y) outside which the kernel's
/// vtPixelCell cannot find a cell of the sprite. Along a row the kernel's pixel -> cell map is
/// q(x) = (a x + b) / (d x + e) per axis, monotone where the denominator is positive, so the
/// pixels whose cell lies in the range form an interval; it is found here in double from the same
/// coefficients, with the range widened by one cell on every side (the float kernel is off by
/// far less than a cell near a sprite) and the columns by one pixel. The sprite's quad rectangle
/// is up to several times its footprint for close, oblique sprites, and every pixel skipped is a
/// reciprocal and two affine forms saved.
std::pair<int, int> candidateColumns(const kernel::SpriteGpu& g, double py, int rx0, int rx1) {
    double lo = -std::numeric_limits<double>::infinity(),
           hi = std::numeric_limits<double>::infinity();
    bool empty = false;
    auto keep = [&](double a, double b) { // keep x with a x + b >= 0
        if (a > 0.0)
            lo = std::max(lo, -b / a);
        else if (a < 0.0)
            hi = std::min(hi, -b / a);
        else if (b < 0.0)
            empty = true;
    };
    const double d = g.mapDen.x, e = double(g.mapDen.y) * py + double(g.mapDen.z);
    keep(d, e); // denominator >= 0
    auto axis = [&](const glm::vec3& m, int first, int last) {
        const double a = m.x, b = double(m.y) * py + double(m.z);
        const double qlo = first - 1.0, qhi = last + 2.0;
        keep(a - qlo * d, b - qlo * e);       // q >= qlo
        keep(-(a - qhi * d), -(b - qhi * e)); // q <= qhi
    };
    axis(g.mapI, g.cellRange.x, g.cellRange.y);
    axis(g.mapJ, g.cellRange.z, g.cellRange.w);
    if (empty || !(lo <= hi)) return {rx0, rx0};
    // Pixel x has its centre at x + 0.5.
    const double x0 = std::clamp(std::floor(lo - 0.5) - 1.0, double(rx0), double(rx1));
    const double x1 = std::clamp(std::ceil(hi - 0.5) + 2.0, double(rx0), double(rx1));
    return {int(x0), std::max(int(x0), int(x1))};
}
} // namespace

void blitFar(std::span<const FarSprite> sprites, Image& target, FarBlitStats* stats) {
    const auto t0 = std::chrono::steady_clock::now();
    // Each row is written by exactly one task (no locks); the depth/id rule makes the result
    // independent of the order sprites are visited in.
    std::vector<std::vector<std::uint32_t>> rows(std::size_t(target.height));
    std::vector<SnapshotCellMap> maps(sprites.size());
    std::uint64_t drawn = 0;
    for (std::uint32_t s = 0; s < sprites.size(); ++s) {
        const FarSprite& f = sprites[s];
        if (!f.sprite || !f.snapshot || !f.palette || !f.sprite->visible()) continue;
        ++drawn;
        maps[s] = snapshotCellMap(f.sprite->lattice, f.snapshot->lattice);
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
                    const SnapshotCellMap& map = maps[s];
                    const Snapshot& snap = *f.snapshot;
                    const kernel::SpriteGpu& g = sp.gpu;
                    // What a pixel shows depends only on its near cell, and neighbouring pixels
                    // mostly share one: the last cell's outcome is reused along the row.
                    glm::ivec2 lastCell(INT_MIN, INT_MIN);
                    bool lastDrawn = false;
                    Rgba8 lastColor = 0;
                    const std::size_t rowBase = target.index(0, y);
                    const auto [x0, x1] =
                        candidateColumns(g, double(py), sp.screenRect.x, sp.screenRect.z);
                    for (int x = x0; x < x1; ++x) {
                        ++rc.tested;
                        glm::ivec2 cell;
                        if (!kernel::vtPixelCell(g, glm::vec2(float(x) + 0.5f, py), cell)) continue;
                        if (cell != lastCell) {
                            lastCell = cell;
                            const glm::ivec2 sc =
                                map(cell); // the snapshot cell under the near cell's centre
                            const SnapshotCell c = snap.at(sc.x, sc.y);
                            lastDrawn = c.code != snapshot_code::kEmpty;
                            if (lastDrawn)
                                lastColor = snapshot_code::isSolid(c.code)
                                                ? kernel::vtLit(f.palette->colors[c.index],
                                                                kernel::vtFaceLight(
                                                                    g, snapshot_code::face(c.code)))
                                                : kernel::VT_OUTLINE_RGBA;
                        }
                        if (!lastDrawn) continue;
                        ++rc.written;
                        target.writeIfNearer(rowBase + std::size_t(x), lastColor, g.depth,
                                             sp.entityId);
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
        stats->milliseconds += msSince(t0);
    }
}

} // namespace voxtier
