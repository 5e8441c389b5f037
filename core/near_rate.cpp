#include "core/near_rate.hpp"

#include "core/running_totals.hpp"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <vector>

namespace voxtier {

std::uint64_t cellCount(const SpriteSetup& s) {
    const glm::ivec4 r = s.gpu.cellRange;
    if (r.y < r.x || r.w < r.z) return 0;
    return std::uint64_t(r.y - r.x + 1) * std::uint64_t(r.w - r.z + 1);
}

std::uint64_t rectPixels(const SpriteSetup& s) {
    const glm::ivec4 r = s.screenRect;
    if (r.z <= r.x || r.w <= r.y) return 0;
    return std::uint64_t(r.z - r.x) * std::uint64_t(r.w - r.y);
}

bool wantsCellRate(std::uint64_t cells, std::uint64_t pixels, NearRate rate) {
    return cells > 0 &&
           (rate == NearRate::Cell ||
            (rate == NearRate::Auto && kCellRateCost * double(cells) < double(pixels)));
}

bool wantsCellRate(const SpriteSetup& s, NearRate rate) {
    return wantsCellRate(cellCount(s), rectPixels(s), rate);
}

double nearCostUnits(std::uint64_t cells, std::uint64_t pixels, NearRate rate) {
    return wantsCellRate(cells, pixels, rate) ? kCellRateCost * double(cells) : double(pixels);
}

double nearCostUnits(const SpriteSetup& s, NearRate rate) {
    return nearCostUnits(cellCount(s), rectPixels(s), rate);
}

CellRateWish cellRateWish(const SpriteSetup& s, NearRate rate) {
    if (!s.visible()) return {};
    return {cellCount(s), rectPixels(s), true, wantsCellRate(s, rate)};
}

CellRatePlan planCellRate(std::span<const SpriteSetup* const> sprites, NearRate rate,
                          std::uint64_t budgetBytes, std::uint64_t maxCellSprites) {
    // Each sprite's wish and sizes in parallel; the budget is then given out in sprite order.
    std::vector<CellRateWish> wishes(sprites.size());
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, sprites.size(), 128), [&](const auto& r) {
        for (std::size_t k = r.begin(); k != r.end(); ++k)
            wishes[k] = cellRateWish(*sprites[k], rate);
    });
    return planCellRate(wishes, budgetBytes, maxCellSprites);
}

namespace {

/// planCellRate's plan where every wanted sprite fits the budget and the sprite cap, over the
/// cores; false (the plan untouched but for cellBase's size) where they do not, or where the
/// wishes are too few or the cores too few to spread them (runningTotalsInParallel).
bool planAllWishesInParallel(std::span<const CellRateWish> wishes, CellRatePlan& plan,
                             std::uint64_t budgetCells, std::uint64_t maxCellSprites) {
    const std::size_t n = wishes.size();
    if (!runningTotalsInParallel(n)) return false;
    const std::size_t chunks = chunkCount(n);
    struct Sums {
        std::uint64_t cells = 0, sprites = 0, pixelsLookedUp = 0, pixelsTraced = 0;
    };
    const auto cellRate = [&](std::size_t k) { return wishes[k].visible && wishes[k].wanted; };
    std::vector<Sums> sums(chunks + 1);
    forEachChunk(n, [&](std::size_t c, std::size_t first, std::size_t end) {
        Sums s;
        for (std::size_t k = first; k != end; ++k) {
            if (!wishes[k].visible) continue;
            if (cellRate(k))
                s.cells += wishes[k].cells, ++s.sprites, s.pixelsLookedUp += wishes[k].pixels;
            else
                s.pixelsTraced += wishes[k].pixels;
        }
        sums[c + 1] = s;
    });
    // The chunks' running totals: sums[c] is everything before chunk c.
    for (std::size_t c = 0; c < chunks; ++c) {
        sums[c + 1].cells += sums[c].cells;
        sums[c + 1].sprites += sums[c].sprites;
        sums[c + 1].pixelsLookedUp += sums[c].pixelsLookedUp;
        sums[c + 1].pixelsTraced += sums[c].pixelsTraced;
    }
    const Sums& all = sums[chunks];
    // Counts are not negative, so every running total fits where the last does.
    if (all.cells > budgetCells || all.sprites > maxCellSprites) return false;
    forEachChunk(n, [&](std::size_t c, std::size_t first, std::size_t end) {
        std::uint64_t cells = sums[c].cells;
        for (std::size_t k = first; k != end; ++k)
            if (cellRate(k)) {
                plan.cellBase[k] = std::uint32_t(cells);
                cells += wishes[k].cells;
            } else {
                plan.cellBase[k] = kNoCells;
            }
    });
    plan.cells = all.cells;
    plan.cellSprites = all.sprites;
    plan.overBudget = 0;
    plan.pixelsTraced = all.pixelsTraced;
    plan.pixelsLookedUp = all.pixelsLookedUp;
    return true;
}

} // namespace

CellRatePlan planCellRate(std::span<const CellRateWish> wishes, std::uint64_t budgetBytes,
                          std::uint64_t maxCellSprites) {
    CellRatePlan plan;
    planCellRate(wishes, plan, budgetBytes, maxCellSprites);
    return plan;
}

void planCellRate(std::span<const CellRateWish> wishes, CellRatePlan& plan,
                  std::uint64_t budgetBytes, std::uint64_t maxCellSprites) {
    std::vector<std::uint32_t> cellBase = std::move(plan.cellBase);
    plan = CellRatePlan{};
    plan.cellBase = std::move(cellBase);
    plan.cellBase.resize(wishes.size());
    // Offsets (up to twice the cell count: the outcomes follow the primaries) are uint32 on the
    // GPU; kNoCells stays out of reach.
    const std::uint64_t budgetCells =
        std::min<std::uint64_t>(budgetBytes / kCellStoreBytesPerCell, kNoCells / 2 - 1);
    // Where every wish fits (the usual frame), each cell-rate sprite's offset is the running
    // total of the cells wished before it, found per chunk of sprites over the cores where there
    // are enough of them: the same integers as the serial pass below (runningTotalsInParallel).
    if (planAllWishesInParallel(wishes, plan, budgetCells, maxCellSprites)) return;
    // Else the budget is given out in sprite order (a running total, so serial), over figures
    // already at hand.
    std::fill(plan.cellBase.begin(), plan.cellBase.end(), kNoCells);
    for (std::size_t k = 0; k < wishes.size(); ++k) {
        if (!wishes[k].visible) continue;
        const std::uint64_t cells = wishes[k].cells, pixels = wishes[k].pixels;
        const bool wanted = wishes[k].wanted;
        const bool fits =
            wanted && plan.cells + cells <= budgetCells && plan.cellSprites < maxCellSprites;
        if (wanted && !fits) ++plan.overBudget;
        if (!fits) {
            plan.pixelsTraced += pixels;
            continue;
        }
        plan.cellBase[k] = std::uint32_t(plan.cells);
        plan.cells += cells;
        ++plan.cellSprites;
        plan.pixelsLookedUp += pixels;
    }
}

} // namespace voxtier
