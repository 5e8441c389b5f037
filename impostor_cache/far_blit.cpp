#include "impostor_cache/far_blit.hpp"

#include "core/row_bands.hpp"
#include "core/stopwatch.hpp"
#include "impostor_cache/detail/far_blit_band.hpp"

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

namespace detail {

/// Along a row the kernel's pixel -> cell map is q(x) = (a x + b) / (d x + e) per axis, monotone
/// where the denominator is positive, so the pixels whose cell lies in the range form an
/// interval; it is found here in double from the same coefficients, with the range widened by
/// one cell on every side (the float kernel is off by far less than a cell near a sprite) and
/// the columns by one pixel. The sprite's quad rectangle is up to several times its footprint
/// for close, oblique sprites, and every pixel skipped is a reciprocal and two affine forms saved.
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

void blitSpriteScalar(const BlitSprite& s, int y0, int y1, Image& target, BlitCounters& rc) {
    const kernel::SpriteGpu& g = *s.gpu;
    const Snapshot& snap = *s.snapshot;
    for (int y = y0; y < y1; ++y) {
        const float py = float(y) + 0.5f;
        // What a pixel shows depends only on its near cell, and neighbouring pixels mostly share
        // one: the last cell's outcome is reused along the row.
        glm::ivec2 lastCell(INT_MIN, INT_MIN);
        bool lastDrawn = false;
        Rgba8 lastColor = 0;
        const std::size_t rowBase = target.index(0, y);
        const auto [x0, x1] = candidateColumns(g, double(py), s.rect.x, s.rect.z);
        rc.tested += std::uint64_t(x1 - x0);
        for (int x = x0; x < x1; ++x) {
            glm::ivec2 cell;
            if (!kernel::vtPixelCell(g, glm::vec2(float(x) + 0.5f, py), cell)) continue;
            if (cell != lastCell) {
                lastCell = cell;
                const glm::ivec2 sc = s.map(cell); // the snapshot cell under the near cell's centre
                const SnapshotCell c = snap.at(sc.x, sc.y);
                lastDrawn = c.code != snapshot_code::kEmpty;
                if (lastDrawn)
                    lastColor =
                        snapshot_code::isSolid(c.code)
                            ? kernel::vtLit(s.palette[c.index],
                                            kernel::vtFaceLight(g, snapshot_code::face(c.code)))
                            : kernel::VT_OUTLINE_RGBA;
            }
            if (!lastDrawn || !target.wouldWrite(rowBase + std::size_t(x), g.depth, s.entity))
                continue;
            ++rc.written;
            target.writeIfNearer(rowBase + std::size_t(x), lastColor, g.depth, s.entity);
        }
    }
}

void blitBandScalar(const BlitBand& band, BlitCounters& counters) {
    for (std::size_t k = 0; k < band.count; ++k)
        drawInBand(band, band.sprites[band.list[k]], counters,
                   [&](const BlitSprite& part, int y0, int y1) {
                       blitSpriteScalar(part, y0, y1, *band.target, counters);
                   });
}

} // namespace detail

void blitFar(std::span<const FarSprite> sprites, Image& target, FarBlitStats* stats,
             const FarBlitOptions& options, OcclusionTiles* tiles) {
    const auto t0 = std::chrono::steady_clock::now();
    using detail::BlitSprite;
    // Each band of rows is written by exactly one task (no locks); the depth/id rule makes the
    // result independent of the order sprites are visited in.
    const int bandRows = std::max(1, options.bandRows);
    const int bands = target.height > 0 ? (target.height + bandRows - 1) / bandRows : 0;
    std::vector<BlitSprite> drawn;
    drawn.reserve(sprites.size());
    for (const FarSprite& f : sprites) {
        if (!f.sprite || !f.snapshot || !f.palette || !f.sprite->visible()) continue;
        const SpriteSetup& sp = *f.sprite;
        BlitSprite b;
        b.gpu = &sp.gpu;
        b.snapshot = f.snapshot;
        b.palette = f.palette->colors.data();
        b.map = snapshotCellMap(sp.lattice, f.snapshot->lattice);
        b.rect = {sp.screenRect.x, sp.screenRect.y, sp.screenRect.z,
                  std::min(sp.screenRect.w, target.height)};
        b.entity = sp.entityId;
        for (unsigned face = 0; face < 6; ++face)
            b.lightByCode[snapshot_code::kSolid0 + face] = kernel::vtFaceLight(sp.gpu, face);
        drawn.push_back(b);
    }
    // Bands can keep occlusion tiles only when they are whole tile rows (each band's tiles its
    // own); the band then draws its sprites front to back, so the tiles fill before the sprites
    // behind them come (a stable sort: the bucketing keeps this order within a band).
    if (tiles && bandRows % OcclusionTiles::kTile != 0) tiles = nullptr;
    if (tiles)
        std::stable_sort(drawn.begin(), drawn.end(), [](const BlitSprite& a, const BlitSprite& b) {
            return a.gpu->depth > b.gpu->depth ||
                   (a.gpu->depth == b.gpu->depth && a.entity < b.entity);
        });
    const RowBands byBand = bucketByBand(drawn.size(), bands, bandRows, [&](std::size_t i) {
        return std::pair<int, int>{drawn[i].rect.y, drawn[i].rect.w};
    });
    const bool simd = options.kernel == FarBlitKernel::Simd;
    tbb::combinable<detail::BlitCounters> counters;
    // A grain of about four rows, as the row layout always had.
    const int grain = std::max(1, 4 / bandRows);
    tbb::parallel_for(
        tbb::blocked_range<int>(0, bands, grain), [&](const tbb::blocked_range<int>& r) {
            detail::BlitCounters& rc = counters.local();
            for (int k = r.begin(); k < r.end(); ++k) {
                detail::BlitBand band;
                band.sprites = drawn.data();
                band.list = byBand.list.data() + byBand.start[std::size_t(k)];
                band.count = byBand.start[std::size_t(k) + 1] - byBand.start[std::size_t(k)];
                band.y0 = k * bandRows;
                band.y1 = std::min(target.height, band.y0 + bandRows);
                band.target = &target;
                band.tiles = tiles;
                if (simd)
                    detail::blitBandSimd(band, rc);
                else
                    detail::blitBandScalar(band, rc);
            }
        });
    if (stats) {
        detail::BlitCounters total;
        counters.combine_each([&](const detail::BlitCounters& c) {
            total.tested += c.tested;
            total.written += c.written;
            total.partsCulled += c.partsCulled;
        });
        stats->sprites += drawn.size();
        stats->pixelsTested += total.tested;
        stats->pixelsWritten += total.written;
        stats->partsCulled += total.partsCulled;
        stats->milliseconds += msSince(t0);
    }
}

} // namespace voxtier
