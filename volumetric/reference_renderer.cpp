#include "volumetric/reference_renderer.hpp"

#include "core/occlusion.hpp"
#include "core/row_bands.hpp"
#include "core/stopwatch.hpp"

#include <tbb/combinable.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <optional>

namespace voxtier {

namespace {

/// The kernel's voxel source on the CPU: the dense grid and its brick occupancy, counting reads
/// when asked to.
template <bool Count> struct GridVoxels {
    const std::uint8_t* data;
    std::size_t sx, sxy;
    const std::uint32_t* brickWords;
    mutable std::uint64_t fetches = 0, brickFetches = 0;
    kernel::uint fetch(glm::ivec3 c) const {
        if constexpr (Count) ++fetches;
        return data[std::size_t(c.x) + sx * std::size_t(c.y) + sxy * std::size_t(c.z)];
    }
    /// Without words (ReferenceOptions::skipEmptyBricks off) every brick is occupied: the
    /// cell-by-cell traversal, which reads no brick.
    kernel::uint fetchBrickWord(kernel::uint word) const {
        if (!brickWords) return 0xFFFFFFFFu;
        if constexpr (Count) ++brickFetches;
        return brickWords[word];
    }
};

template <bool Count> GridVoxels<Count> voxelsOf(const VoxelGrid& g, const BrickOccupancy* bricks) {
    return {g.data().data(), std::size_t(g.dims().x),
            std::size_t(g.dims().x) * std::size_t(g.dims().y),
            bricks ? bricks->words().data() : nullptr};
}

struct RowCounters {
    std::uint64_t tested = 0, hidden = 0, inSprite = 0, written = 0, fetches = 0, brickFetches = 0,
                  traced = 0, lookedUp = 0, cellsTraced = 0;
};

/// The cell-rate sprites' cells (core/near_rate.hpp), traced on first use rather than all before
/// the pixels: a cell's primary ray is traced the first time a pixel of it or of one of its four
/// neighbours needs it (vtOutcomeFromPrimaries reads all five), so the cells under pixels the
/// early depth test rejects, or that occlusion tiles skip, are never traced. A cell may be needed
/// by two band tasks at once (a magnified cell spans bands): both trace it and store the same value
/// (the kernel is deterministic), through atomic_ref so that the race is a defined one.
struct LazyCells {
    static constexpr kernel::uint kUnknown = 0xFFFFFFFFu; // no packed outcome has all bits set
    std::vector<kernel::uint> primaries, outcomes;
    explicit LazyCells(std::uint64_t cells)
        : primaries(std::size_t(cells), kUnknown), outcomes(std::size_t(cells), kUnknown) {}
};

/// A memoised slot: its value, computing and storing it with `make` the first time. Two bands of
/// rows may both find the slot unknown and both compute it (the same value, so harmless); only
/// the store that fills the slot adds to `filled`, so a count of cells traced is the number of
/// distinct cells, whatever the threads' timing (it was not: 1 run in 100 of
/// ReferenceCellRate.SpritesPastTheCellBudgetFallBackToPerPixel counted 398 of 396 cells).
template <class Make>
kernel::uint memoised(kernel::uint& slot, Make&& make, std::uint64_t* filled = nullptr) {
    std::atomic_ref<kernel::uint> ref(slot);
    kernel::uint v = ref.load(std::memory_order_relaxed);
    if (v == LazyCells::kUnknown) {
        v = make();
        kernel::uint expected = LazyCells::kUnknown;
        if (ref.compare_exchange_strong(expected, v, std::memory_order_relaxed) && filled)
            ++*filled;
    }
    return v;
}

/// One sprite's rows [y0, y1), columns [x0, x1): every pixel the depth/id rule may still let the
/// sprite write gets its kernel outcome (traced, or from its cell), shaded and written. `open(x)`
/// says whether the occlusion tile holding column x may still take the sprite.
template <class Open>
void drawSpriteRows(const std::vector<std::shared_ptr<VoxelModel>>& models, const SpriteSetup& sp,
                    kernel::uint cellBase, LazyCells& cells, int y0, int y1, int x0, int x1,
                    Open&& open, bool earlyDepth, bool skipBricks, Image& target, RowCounters& rc) {
    const VoxelModel& model = *models[std::size_t(sp.model)];
    const auto voxels =
        voxelsOf<true>(model.frame(sp.frame), skipBricks ? &model.bricks(sp.frame) : nullptr);
    kernel::SpriteTracer<GridVoxels<true>> tracer{voxels};
    const kernel::SpriteGpu& g = sp.gpu;
    for (int y = y0; y < y1; ++y) {
        const float py = float(y) + 0.5f;
        for (int x = x0; x < x1; ++x) {
            if (!open(x)) { // a hidden tile: on to the next one
                x = (x / OcclusionTiles::kTile + 1) * OcclusionTiles::kTile - 1;
                continue;
            }
            ++rc.tested;
            // Early depth test: the sprite writes one depth everywhere, so where the pixel already
            // holds what the depth/id rule keeps against it, no outcome of the kernel can be
            // written, and the pixel is neither traced nor looked up. Exact by construction: the
            // test is the write's own condition, taken before the work instead of after.
            const std::size_t p = target.index(x, y);
            if (earlyDepth && !target.wouldWrite(p, g.depth, sp.entityId)) {
                ++rc.hidden;
                continue;
            }
            glm::ivec2 cell;
            const glm::vec2 pc(float(x) + 0.5f, py);
            if (!kernel::vtPixelCell(g, pc, cell)) continue;
            ++rc.inSprite;
            kernel::uint index, face, kind;
            if (cellBase == kNoCells) {
                ++rc.traced;
                kind = tracer.vtShadeCell(g, cell, index, face);
            } else {
                ++rc.lookedUp;
                const auto primary = [&](glm::ivec2 c) -> kernel::uint {
                    if (!kernel::vtCellInRange(g, c)) return kernel::VT_KIND_EMPTY;
                    return memoised(
                        cells.primaries[cellBase + kernel::vtCellSlot(g, c)],
                        [&] { return tracer.vtTraceCellPrimary(g, c); }, &rc.cellsTraced);
                };
                const kernel::uint outcome =
                    memoised(cells.outcomes[cellBase + kernel::vtCellSlot(g, cell)], [&] {
                        return kernel::vtOutcomeFromPrimaries(
                            primary(cell), primary(cell + glm::ivec2(-1, 0)),
                            primary(cell + glm::ivec2(1, 0)), primary(cell + glm::ivec2(0, -1)),
                            primary(cell + glm::ivec2(0, 1)));
                    });
                kind = kernel::vtUnpackOutcome(outcome, index, face);
            }
            if (kind == kernel::VT_KIND_EMPTY) continue;
            ++rc.written;
            const Rgba8 color =
                kind == kernel::VT_KIND_SOLID
                    ? kernel::vtLit(model.palette().colors[index], kernel::vtFaceLight(g, face))
                    : kernel::VT_OUTLINE_RGBA;
            target.writeIfNearer(p, color, g.depth, sp.entityId);
        }
    }
    rc.fetches += voxels.fetches + voxels.brickFetches;
    rc.brickFetches += voxels.brickFetches;
}

} // namespace

void renderReference(const std::vector<std::shared_ptr<VoxelModel>>& models,
                     std::span<const SpriteSetup* const> sprites, Image& target,
                     ReferenceStats* stats, const ReferenceOptions& options) {
    const auto t0 = std::chrono::steady_clock::now();
    // With culling a band is one tile row (its tiles its own); without, 4 rows, the grain the
    // row-parallel pass always had.
    const int bandRows = options.occlusionCull ? OcclusionTiles::kTile : 4;
    // With culling the sprites go front to back in runs (core/occlusion.hpp): a run's sprites are
    // tested whole against what the runs before drew, so a hidden sprite traces no cell, and the
    // rest skip the tiles that already hide them. Without, one run: front to back under the early
    // depth test (so it rejects most of a crowd), else in the order given.
    const std::vector<std::uint32_t> order =
        drawOrder(sprites, options.occlusionCull || options.earlyDepthTest);
    std::optional<OcclusionTiles> tiles;
    if (options.occlusionCull) tiles.emplace(target);
    const int bands = (target.height + bandRows - 1) / bandRows;

    tbb::combinable<RowCounters> counters;
    std::uint64_t drawn = 0;
    CellRateCounts rate;
    std::vector<const SpriteSetup*> run;
    const std::size_t culled = drawFrontToBack(
        order, sprites, tiles ? &*tiles : nullptr, occlusionRunPixels(target.pixelCount()),
        [&](std::span<const std::uint32_t> indices) {
            run.clear();
            for (const std::uint32_t i : indices) run.push_back(sprites[i]);
            drawn += run.size();
            const CellRatePlan plan = planCellRate(run, options.rate, options.cellBudgetBytes);
            LazyCells cells(plan.cells);
            rate.cellSprites += plan.cellSprites;
            rate.cellOverBudget += plan.overBudget;
            // Bucketed by band of rows, each band written by exactly one task (no locks; the
            // depth/id rule makes the image independent of the order sprites are visited in).
            const RowBands byBand = bucketByBand(run.size(), bands, bandRows, [&](std::size_t i) {
                return std::pair<int, int>{run[i]->screenRect.y,
                                           std::min(run[i]->screenRect.w, target.height)};
            });
            if (options.progress) {
                std::uint64_t rows = 0;
                for (const SpriteSetup* sp : run)
                    rows += std::uint64_t(std::max(0, std::min(sp->screenRect.w, target.height) -
                                                          std::max(sp->screenRect.y, 0)));
                options.progress->total.fetch_add(rows, std::memory_order_relaxed);
            }
            tbb::parallel_for(0, bands, [&](int b) {
                RowCounters& rc = counters.local();
                const int y0 = b * bandRows, y1 = std::min(target.height, y0 + bandRows);
                std::uint64_t rowsDone = 0;
                for (std::uint32_t k = byBand.start[std::size_t(b)];
                     k < byBand.start[std::size_t(b) + 1]; ++k) {
                    const std::uint32_t i = byBand.list[k];
                    const SpriteSetup& sp = *run[i];
                    const int r0 = std::max(sp.screenRect.y, y0),
                              r1 = std::min(sp.screenRect.w, y1);
                    rowsDone += std::uint64_t(std::max(0, r1 - r0));
                    if (!tiles) {
                        drawSpriteRows(
                            models, sp, plan.cellBase[i], cells, r0, r1, sp.screenRect.x,
                            sp.screenRect.z, [](int) { return true; }, options.earlyDepthTest,
                            options.skipEmptyBricks, target, rc);
                        continue;
                    }
                    const auto [x0, x1] =
                        tiles->visibleColumns(b, sp.screenRect.x, sp.screenRect.z, sp.gpu.depth);
                    if (x0 >= x1) continue;
                    // Which tiles between the two ends are still open, read once per sprite and
                    // band.
                    thread_local std::vector<char> open;
                    constexpr int kTile = OcclusionTiles::kTile;
                    const int c0 = x0 / kTile;
                    open.resize(std::size_t((x1 - 1) / kTile - c0 + 1));
                    for (std::size_t c = 0; c < open.size(); ++c)
                        open[c] = tiles->tileOpen(b, (c0 + int(c)) * kTile, sp.gpu.depth);
                    drawSpriteRows(
                        models, sp, plan.cellBase[i], cells, r0, r1, x0, x1,
                        [&](int x) { return open[std::size_t(x / kTile - c0)] != 0; },
                        options.earlyDepthTest, options.skipEmptyBricks, target, rc);
                    tiles->drawn(b, x0, x1, r1 - r0);
                }
                if (options.progress)
                    options.progress->done.fetch_add(rowsDone, std::memory_order_relaxed);
            });
        });
    if (stats) {
        RowCounters total;
        counters.combine_each([&](const RowCounters& c) {
            total.tested += c.tested;
            total.hidden += c.hidden;
            total.inSprite += c.inSprite;
            total.written += c.written;
            total.fetches += c.fetches;
            total.brickFetches += c.brickFetches;
            total.traced += c.traced;
            total.lookedUp += c.lookedUp;
            total.cellsTraced += c.cellsTraced;
        });
        stats->sprites += drawn;
        stats->culled += culled;
        stats->pixelsTested += total.tested;
        stats->pixelsHidden += total.hidden;
        stats->pixelsInSprite += total.inSprite;
        stats->pixelsWritten += total.written;
        stats->voxelFetches += total.fetches;
        stats->brickFetches += total.brickFetches;
        stats->pixelsTraced += total.traced;
        stats->pixelsLookedUp += total.lookedUp;
        stats->cellsTraced += total.cellsTraced;
        stats->cellSprites += rate.cellSprites;
        stats->cellOverBudget += rate.cellOverBudget;
        stats->milliseconds += msSince(t0);
    }
}

void renderReference(const std::vector<std::shared_ptr<VoxelModel>>& models,
                     const std::vector<SpriteSetup>& all, Image& target, ReferenceStats* stats,
                     const ReferenceOptions& options) {
    std::vector<const SpriteSetup*> ptrs;
    ptrs.reserve(all.size());
    for (const auto& s : all) ptrs.push_back(&s);
    renderReference(models, ptrs, target, stats, options);
}

CellImage traceCells(const kernel::SpriteGpu& g, const VoxelGrid& grid) {
    CellImage out;
    out.range = g.cellRange;
    const std::size_t n = std::size_t(out.width()) * std::size_t(out.height());
    out.kind.assign(n, 0);
    out.index.assign(n, 0);
    out.face.assign(n, 0);
    const BrickOccupancy bricks(grid);
    const auto voxels = voxelsOf<false>(grid, &bricks);
    kernel::SpriteTracer<GridVoxels<false>> tracer{voxels};
    for (int j = out.range.z; j <= out.range.w; ++j)
        for (int i = out.range.x; i <= out.range.y; ++i) {
            kernel::uint index, face;
            const std::size_t k = out.at(i, j);
            out.kind[k] = std::uint8_t(tracer.vtShadeCell(g, {i, j}, index, face));
            out.index[k] = std::uint8_t(index);
            out.face[k] = std::uint8_t(face);
        }
    return out;
}

} // namespace voxtier
