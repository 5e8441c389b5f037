#include "core/near_rate.hpp"

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

bool wantsCellRate(const SpriteSetup& s, NearRate rate) {
    const std::uint64_t cells = cellCount(s);
    return cells > 0 &&
           (rate == NearRate::Cell ||
            (rate == NearRate::Auto && kCellRateCost * double(cells) < double(rectPixels(s))));
}

double nearCostUnits(const SpriteSetup& s, NearRate rate) {
    return wantsCellRate(s, rate) ? kCellRateCost * double(cellCount(s)) : double(rectPixels(s));
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
    plan.cellBase.assign(wishes.size(), kNoCells);
    // Offsets (up to twice the cell count: the outcomes follow the primaries) are uint32 on the
    // GPU; kNoCells stays out of reach.
    const std::uint64_t budgetCells =
        std::min<std::uint64_t>(budgetBytes / kCellStoreBytesPerCell, kNoCells / 2 - 1);
    // The budget is given out in sprite order (a running total, so serial), over figures
    // already at hand.
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
