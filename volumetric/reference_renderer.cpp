#include "volumetric/reference_renderer.hpp"

#include "core/stopwatch.hpp"

#include <tbb/combinable.h>
#include <tbb/parallel_for.h>

#include <chrono>

namespace voxtier {

namespace {

/// The kernel's voxel source on the CPU: the dense grid, counting reads when asked to.
template <bool Count> struct GridVoxels {
    const std::uint8_t* data;
    std::size_t sx, sxy;
    mutable std::uint64_t fetches = 0;
    kernel::uint fetch(glm::ivec3 c) const {
        if constexpr (Count) ++fetches;
        return data[std::size_t(c.x) + sx * std::size_t(c.y) + sxy * std::size_t(c.z)];
    }
};

template <bool Count> GridVoxels<Count> voxelsOf(const VoxelGrid& g) {
    return {g.data().data(), std::size_t(g.dims().x),
            std::size_t(g.dims().x) * std::size_t(g.dims().y)};
}

struct RowCounters {
    std::uint64_t tested = 0, inSprite = 0, written = 0, fetches = 0, traced = 0, lookedUp = 0;
};

/// Pass 1 of cell-rate (near_rate.hpp): the primary ray of every cell of every cell-rate sprite
/// traced once with the kernel, then every cell's outcome from its and its neighbours' primaries
/// (vtOutcomeFromPrimaries), TBB-parallel over sprites and their cell rows. Returns the outcomes
/// at the plan's offsets.
std::vector<kernel::uint>
traceCellRateSprites(const std::vector<std::shared_ptr<VoxelModel>>& models,
                     std::span<const SpriteSetup* const> sprites, const CellRatePlan& plan,
                     tbb::combinable<RowCounters>& counters) {
    std::vector<kernel::uint> primaries(plan.cells), outcomes(plan.cells);
    std::vector<std::size_t> cellSprites;
    for (std::size_t s = 0; s < sprites.size(); ++s)
        if (plan.cellBase[s] != kNoCells) cellSprites.push_back(s);
    // Over the rows of every cell-rate sprite: body(sprite index, its SpriteGpu, first row, end).
    const auto overRows = [&](const auto& body) {
        tbb::parallel_for(std::size_t(0), cellSprites.size(), [&](std::size_t k) {
            const std::size_t s = cellSprites[k];
            const kernel::SpriteGpu& g = sprites[s]->gpu;
            const int rows = g.cellRange.w - g.cellRange.z + 1;
            tbb::parallel_for(tbb::blocked_range<int>(0, rows, 4),
                              [&](const tbb::blocked_range<int>& r) {
                                  const kernel::uint rowLength = kernel::vtCellRowLength(g);
                                  body(s, g, kernel::uint(r.begin()) * rowLength,
                                       kernel::uint(r.end()) * rowLength);
                              });
        });
    };
    overRows([&](std::size_t s, const kernel::SpriteGpu& g, kernel::uint first, kernel::uint last) {
        const SpriteSetup& sp = *sprites[s];
        const auto voxels = voxelsOf<true>(models[std::size_t(sp.model)]->frame(sp.frame));
        kernel::SpriteTracer<GridVoxels<true>> tracer{voxels};
        for (kernel::uint slot = first; slot < last; ++slot)
            primaries[plan.cellBase[s] + slot] =
                tracer.vtTraceCellPrimary(g, kernel::vtSlotCell(g, slot));
        counters.local().fetches += voxels.fetches;
    });
    overRows([&](std::size_t s, const kernel::SpriteGpu& g, kernel::uint first, kernel::uint last) {
        const kernel::uint base = plan.cellBase[s];
        const auto primaryAt = [&](glm::ivec2 c) {
            return kernel::vtCellInRange(g, c) ? primaries[base + kernel::vtCellSlot(g, c)]
                                               : kernel::VT_KIND_EMPTY;
        };
        for (kernel::uint slot = first; slot < last; ++slot) {
            const glm::ivec2 c = kernel::vtSlotCell(g, slot);
            outcomes[base + slot] = kernel::vtOutcomeFromPrimaries(
                primaryAt(c), primaryAt(c + glm::ivec2(-1, 0)), primaryAt(c + glm::ivec2(1, 0)),
                primaryAt(c + glm::ivec2(0, -1)), primaryAt(c + glm::ivec2(0, 1)));
        }
    });
    return outcomes;
}

} // namespace

void renderReference(const std::vector<std::shared_ptr<VoxelModel>>& models,
                     std::span<const SpriteSetup* const> sprites, Image& target,
                     ReferenceStats* stats, const ReferenceOptions& options) {
    const auto t0 = std::chrono::steady_clock::now();
    // Bucket sprites by row so each row is written by exactly one task (no locks, and the
    // depth/id rule makes the result independent of the order sprites are visited in).
    std::vector<std::vector<std::uint32_t>> rows(std::size_t(target.height));
    std::uint64_t drawn = 0;
    for (std::uint32_t s = 0; s < sprites.size(); ++s) {
        const SpriteSetup& sp = *sprites[s];
        if (!sp.visible()) continue;
        ++drawn;
        for (int y = sp.screenRect.y; y < std::min(sp.screenRect.w, target.height); ++y)
            rows[std::size_t(y)].push_back(s);
    }
    tbb::combinable<RowCounters> counters;
    const CellRatePlan plan = planCellRate(sprites, options.rate, options.cellBudgetBytes);
    const std::vector<kernel::uint> cells = traceCellRateSprites(models, sprites, plan, counters);
    // Pass 2: every pixel of every sprite's rectangle; per-pixel sprites trace, cell-rate ones
    // look their cell's outcome up. Either way the same kernel outcome reaches the same shading.
    tbb::parallel_for(
        tbb::blocked_range<int>(0, target.height, 4), [&](const tbb::blocked_range<int>& r) {
            RowCounters& rc = counters.local();
            for (int y = r.begin(); y < r.end(); ++y) {
                for (std::uint32_t s : rows[std::size_t(y)]) {
                    const SpriteSetup& sp = *sprites[s];
                    const VoxelModel& model = *models[std::size_t(sp.model)];
                    const VoxelGrid& grid = model.frame(sp.frame);
                    const auto voxels = voxelsOf<true>(grid);
                    kernel::SpriteTracer<GridVoxels<true>> tracer{voxels};
                    const kernel::SpriteGpu& g = sp.gpu;
                    const kernel::uint cellBase = plan.cellBase[s];
                    const float py = float(y) + 0.5f;
                    for (int x = sp.screenRect.x; x < sp.screenRect.z; ++x) {
                        ++rc.tested;
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
                            kind = kernel::vtUnpackOutcome(
                                cells[cellBase + kernel::vtCellSlot(g, cell)], index, face);
                        }
                        if (kind == kernel::VT_KIND_EMPTY) continue;
                        ++rc.written;
                        const Rgba8 color = kind == kernel::VT_KIND_SOLID
                                                ? kernel::vtLit(model.palette().colors[index],
                                                                kernel::vtFaceLight(g, face))
                                                : kernel::VT_OUTLINE_RGBA;
                        target.writeIfNearer(target.index(x, y), color, g.depth, sp.entityId);
                    }
                    rc.fetches += voxels.fetches;
                }
            }
        });
    if (stats) {
        RowCounters total;
        counters.combine_each([&](const RowCounters& c) {
            total.tested += c.tested;
            total.inSprite += c.inSprite;
            total.written += c.written;
            total.fetches += c.fetches;
            total.traced += c.traced;
            total.lookedUp += c.lookedUp;
        });
        stats->sprites += drawn;
        stats->pixelsTested += total.tested;
        stats->pixelsInSprite += total.inSprite;
        stats->pixelsWritten += total.written;
        stats->voxelFetches += total.fetches;
        stats->pixelsTraced += total.traced;
        stats->pixelsLookedUp += total.lookedUp;
        stats->cellsTraced += plan.cells;
        stats->cellSprites += plan.cellSprites;
        stats->cellOverBudget += plan.overBudget;
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
    const auto voxels = voxelsOf<false>(grid);
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
