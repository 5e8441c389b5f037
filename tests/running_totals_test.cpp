// The chunked passes of the near tier's lists and the cell-rate plan (core/running_totals.hpp):
// the same integers as one core's pass, at the sizes around the chunk and at a 100,000-sprite
// frame's, in an arena of one thread (the serial pass) and of eight (the chunked one, whatever
// cores the machine has).
#include "core/near_rate.hpp"
#include "core/running_totals.hpp"

#include <gtest/gtest.h>
#include <tbb/task_arena.h>

#include <cstdint>
#include <random>
#include <string>
#include <vector>

namespace voxtier {
namespace {

TEST(RunningTotals, EqualASerialSumAroundTheChunkSizesOnOneThreadAndOnEight) {
    const std::size_t c = kRunningTotalsChunk;
    for (const int threads : {1, 8}) {
        tbb::task_arena arena(threads);
        arena.execute([&] {
            EXPECT_EQ(runningTotalsInParallel(100000), threads >= 4);
            std::mt19937_64 rng(7);
            std::vector<std::uint64_t> scratch;
            for (std::size_t n : {std::size_t(0), std::size_t(1), c - 1, c, 2 * c - 1, 2 * c,
                                  2 * c + 1, 3 * c + 5, std::size_t(100000)}) {
                // Counts with runs of zeros (unranked sprites) and a few large ones.
                std::vector<std::uint64_t> starts(n + 1, 12345); // starts[0] is not read
                for (std::size_t k = 0; k < n; ++k)
                    starts[k + 1] =
                        rng() % 3 == 0 ? 0 : (rng() % 50 == 0 ? rng() % 100000 : rng() % 9);
                std::vector<std::uint64_t> expected(n + 1, 0);
                for (std::size_t k = 0; k < n; ++k) expected[k + 1] = expected[k] + starts[k + 1];
                runningTotals(starts, scratch);
                EXPECT_EQ(starts, expected) << n << " items, " << threads << " threads";
            }
        });
    }
}

/// The plan as the contract gives it (core/near_rate.hpp): the budget handed out in sprite order.
CellRatePlan servedInOrder(const std::vector<CellRateWish>& wishes, std::uint64_t budgetBytes,
                           std::uint64_t maxCellSprites) {
    CellRatePlan plan;
    plan.cellBase.assign(wishes.size(), kNoCells);
    const std::uint64_t budgetCells = budgetBytes / kCellStoreBytesPerCell;
    for (std::size_t k = 0; k < wishes.size(); ++k) {
        const CellRateWish& w = wishes[k];
        if (!w.visible) continue;
        if (w.wanted && plan.cells + w.cells <= budgetCells && plan.cellSprites < maxCellSprites) {
            plan.cellBase[k] = std::uint32_t(plan.cells);
            plan.cells += w.cells;
            ++plan.cellSprites;
            plan.pixelsLookedUp += w.pixels;
        } else {
            plan.overBudget += w.wanted;
            plan.pixelsTraced += w.pixels;
        }
    }
    return plan;
}

// Every wish fitting (the chunked pass on eight threads), the budget running out part way and the
// sprite cap reached (the serial pass), over one plan reused as a frame reuses it.
TEST(CellRatePlanInChunks, EqualsTheBudgetServedInSpriteOrder) {
    for (const int threads : {1, 8}) {
        tbb::task_arena arena(threads);
        arena.execute([&] {
            std::mt19937_64 rng(11);
            CellRatePlan plan;
            for (std::size_t n :
                 {std::size_t(5), 2 * kRunningTotalsChunk + 3, std::size_t(30000)}) {
                std::vector<CellRateWish> wishes(n);
                std::uint64_t wantedCells = 0, wantedSprites = 0;
                for (CellRateWish& w : wishes) {
                    w.visible = rng() % 8 != 0;
                    w.wanted = w.visible && rng() % 3 != 0;
                    w.cells = w.visible ? rng() % 400 : 0;
                    w.pixels = w.visible ? rng() % 900 : 0;
                    if (w.wanted) wantedCells += w.cells, ++wantedSprites;
                }
                struct Case {
                    const char* what;
                    std::uint64_t budgetBytes, maxCellSprites;
                    bool allFit;
                };
                const Case cases[] = {
                    {"every wish fits", (wantedCells + 1) * kCellStoreBytesPerCell, wantedSprites,
                     true},
                    {"the budget runs out", wantedCells / 2 * kCellStoreBytesPerCell,
                     kMaxCellSprites, false},
                    {"the sprite cap is reached", kDefaultCellBudgetBytes * 64, wantedSprites / 3,
                     false},
                };
                for (const Case& c : cases) {
                    const CellRatePlan expected =
                        servedInOrder(wishes, c.budgetBytes, c.maxCellSprites);
                    planCellRate(wishes, plan, c.budgetBytes, c.maxCellSprites);
                    const std::string what = std::string(c.what) + ", " + std::to_string(n) +
                                             " wishes, " + std::to_string(threads) + " threads";
                    EXPECT_EQ(plan.cellBase, expected.cellBase) << what;
                    EXPECT_EQ(plan.cells, expected.cells) << what;
                    EXPECT_EQ(plan.cellSprites, expected.cellSprites) << what;
                    EXPECT_EQ(plan.overBudget, expected.overBudget) << what;
                    EXPECT_EQ(plan.pixelsTraced, expected.pixelsTraced) << what;
                    EXPECT_EQ(plan.pixelsLookedUp, expected.pixelsLookedUp) << what;
                    EXPECT_EQ(expected.overBudget == 0, c.allFit) << what << ": as the case says";
                }
            }
        });
    }
}

} // namespace
} // namespace voxtier
