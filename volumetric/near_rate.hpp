#pragma once
// Cell-rate near sprites (DESIGN.md §3.11). A sprite's image is a function of its lattice cells
// (§3.5): every pixel of a magnified sprite that lands in one cell traces that cell's very rays.
// A cell-rate sprite traces each cell of its cellRange once (the kernel's vtTraceCellPrimary),
// adds the outline from the neighbours' primaries (vtOutcomeFromPrimaries: they are exactly
// vtShadeCell's neighbour rays) and shades its pixels by looking the cell up; the image is the same
// bit for bit, because the same kernel functions run on the same floats and only the number of
// times they run changes. Both near backends (the CPU reference and Vulkan) decide per sprite with
// planCellRate.
#include "core/sprite.hpp"

#include <cstdint>
#include <span>
#include <vector>

namespace voxtier {

/// Who traces a near sprite's rays.
enum class NearRate {
    Auto,     ///< cell-rate where kCellRateCost * cells < covered pixels (default)
    Fragment, ///< every pixel traces its cell's rays (seed 000's single fragment pass)
    Cell,     ///< every sprite cell-rate (while the cell budget lasts): for tests
};

/// Auto draws a sprite cell-rate when kCellRateCost * C < P (C: cells of its cellRange, P: the
/// pixels of its on-screen rectangle). Cell-rate costs C * t_cell in the compute pass and saves
/// P' * (t_trace - t_lookup) in the draw (P' fragments, about 0.78 P), so it pays from
/// C / P < 0.78 (t_trace - t_lookup) / t_cell. Measured on Mesa lavapipe (llvmpipe 15, 2-core
/// machine shared with other builds) with
///   voxtier bench scenes/bench/street.json --quick --no-sweeps --no-scaling
/// (near_vulkan against near_vulkan_fragment, same run, medians): t_trace = 219 ns per fragment
/// (146.4 ms / 669704), t_lookup = 132 ns, t_cell = 302 ns (17.1 ms compute / 56444 cells), so
/// C / P < 0.78 * 87 / 302 = 1 / 4.5; rounded down to 4 (DESIGN.md §3.11). The CPU reference
/// uses the same rule (its lookups are cheaper: a smaller k would do there too).
inline constexpr double kCellRateCost = 4.0;

/// Bytes of cell store per cell: the primary outcome and the full outcome, one uint each (the
/// outline pass reads the first and writes the second).
inline constexpr std::uint64_t kCellStoreBytesPerCell = 8;
/// This many bytes of cell store per frame at most (a σ 16 crowd of 256³ models would need
/// gigabytes). Sprites past the budget fall back to per-pixel tracing.
inline constexpr std::uint64_t kDefaultCellBudgetBytes = std::uint64_t(64) << 20;

/// Marks a sprite that is traced per pixel in CellRatePlan::cellBase.
inline constexpr std::uint32_t kNoCells = 0xFFFFFFFFu;

struct CellRatePlan {
    /// Per sprite (the order given): offset of its first cell in the frame's cell store, or
    /// kNoCells when it is traced per pixel.
    std::vector<std::uint32_t> cellBase;
    std::uint64_t cells = 0;          ///< cells to trace (the store's size)
    std::uint64_t cellSprites = 0;    ///< sprites drawn cell-rate
    std::uint64_t overBudget = 0;     ///< sprites the rate chose cell-rate that did not fit
    std::uint64_t pixelsTraced = 0;   ///< on-screen rectangle pixels of per-pixel sprites
    std::uint64_t pixelsLookedUp = 0; ///< on-screen rectangle pixels of cell-rate sprites
};

/// Cells of a sprite's cellRange (0 when empty).
std::uint64_t cellCount(const SpriteSetup& sprite);
/// Pixels of a sprite's screen rectangle (already clamped to the image).
std::uint64_t rectPixels(const SpriteSetup& sprite);

/// Chooses the rate of every sprite in order (visible ones; others get kNoCells) and lays out
/// the cell store, at most budgetBytes of it.
CellRatePlan planCellRate(std::span<const SpriteSetup* const> sprites, NearRate rate,
                          std::uint64_t budgetBytes = kDefaultCellBudgetBytes);

} // namespace voxtier
