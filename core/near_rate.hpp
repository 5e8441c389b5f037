#pragma once
// Cell-rate near sprites (CONTRACT.md §3.11). A sprite's image is a function of its lattice cells
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
    Fragment, ///< every pixel traces its cell's rays itself (no cell store)
    Cell,     ///< every sprite cell-rate (while the cell budget lasts): for tests
};

/// How the Vulkan near tier traces its per-pixel sprites (those not cell-rate); the same image
/// either way (volumetric/near_passes.hpp).
enum class NearPixels {
    Auto,    ///< Compute on a GPU, Raster on a CPU device such as lavapipe (default; why, with the
             ///< figures of both: docs/decisions/near-pixels-in-compute.md)
    Compute, ///< the trace pass: every pixel of their screen rectangles in a compute shader,
             ///< composed with the cell-rate pixels by depth rank (no rasteriser, no proxies)
    Raster,  ///< the draw: their proxies rasterised, the kernel in the fragment shader, under the
             ///< early depth test
};

/// Where each drawn sprite's record lies in the buffer the shaders read (every place in the
/// draw order finds its record through a second buffer, volumetric/shaders/near_sprites.h): the
/// same image either way.
enum class NearRecords {
    /// At its place in the draw order (default): the host gathers each record from the sprites
    /// given, in draw order (a jump through a store's 640-byte sprites apiece), and the device
    /// reads the records in sequence. On llvmpipe, whose device is the host's cores, the other
    /// way's scattered reads cost the draw more than the gather.
    Drawn,
    /// At the sprite's place in the order given (a store's: entity order): the host reads the
    /// sprites in sequence, the device each record through its place (100,000 moving tanks on
    /// the 2-core host: the records' loop 1.0-1.6 ms shorter, llvmpipe's device frame 0-12 %
    /// longer). Meant for a GPU, whose caches take the scattered reads; its figures decide the
    /// default (docs/decisions/entity-scaling.md, stop 70).
    Given,
};

/// Auto draws a sprite cell-rate when kCellRateCost * C < P (C: cells of its cellRange, P: the
/// pixels of its on-screen rectangle). Cell-rate costs a primary ray per cell plus a cheap
/// lookup per rectangle pixel (compute passes); per-pixel costs a fragment, and its rays, per
/// covered pixel. Both near backends use this rule (CONTRACT.md §3.11); why k = 1:
/// docs/decisions/near-cell-rate.md.
inline constexpr double kCellRateCost = 1.0;

/// Bytes of cell store per cell: the primary outcome and the full outcome, one uint each (the
/// outline pass reads the first and writes the second).
inline constexpr std::uint64_t kCellStoreBytesPerCell = 8;
/// This many bytes of cell store per frame at most (a σ 16 crowd of 256³ models would need
/// gigabytes). Sprites past the budget fall back to per-pixel tracing.
inline constexpr std::uint64_t kDefaultCellBudgetBytes = std::uint64_t(64) << 20;

/// At most this many sprites a frame are drawn cell-rate: the Vulkan splat orders them by a depth
/// rank held in 19 bits of a pixel word (volumetric/shaders/near_shared.h NEAR_MAX_CELL_SPRITES).
/// The rest fall back to per-pixel tracing, counted as over budget.
inline constexpr std::uint64_t kMaxCellSprites = std::uint64_t(1) << 19;

/// Marks a sprite that is traced per pixel in CellRatePlan::cellBase.
inline constexpr std::uint32_t kNoCells = 0xFFFFFFFFu;

/// What a near backend's frame did at each rate (both backends' stats carry it).
struct CellRateCounts {
    std::uint64_t cellsTraced = 0;    ///< cells traced once for cell-rate sprites
    std::uint64_t cellSprites = 0;    ///< sprites drawn cell-rate
    std::uint64_t cellOverBudget = 0; ///< sprites that wanted cell-rate but did not fit the budget
    /// Pixels traced per pixel and pixels looked up from a cell: counted by the CPU reference;
    /// on Vulkan the on-screen rectangle pixels of per-pixel and of cell-rate sprites (the plan's
    /// estimate; NearStats::fragmentInvocations counts what the rasteriser ran).
    std::uint64_t pixelsTraced = 0, pixelsLookedUp = 0;
};

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
/// Whether `rate` draws the (visible) sprite cell-rate, as long as the cell budget lasts.
bool wantsCellRate(const SpriteSetup& sprite, NearRate rate);
/// The same from the sprite's cellCount and rectPixels.
bool wantsCellRate(std::uint64_t cells, std::uint64_t rectPixels, NearRate rate);
/// What drawing the sprite near costs in the unit kCellRateCost is measured in (one pixel's
/// fragment): kCellRateCost * cells where `rate` draws it cell-rate, else its rectangle pixels.
/// The far tier's cost bound (CONTRACT.md §5) weighs each sprite by it: since cell-rate, a
/// magnified sprite costs its cells, not its pixels.
double nearCostUnits(const SpriteSetup& sprite, NearRate rate);
/// The same from the sprite's cellCount and rectPixels (SpriteSelectionInputs keeps both).
double nearCostUnits(std::uint64_t cells, std::uint64_t rectPixels, NearRate rate);

/// What the rate plan reads of one sprite: its cells and rectangle pixels, whether it is
/// visible, and whether `rate` draws it cell-rate (wantsCellRate).
struct CellRateWish {
    std::uint64_t cells = 0, pixels = 0;
    bool visible = false, wanted = false;
};
CellRateWish cellRateWish(const SpriteSetup& sprite, NearRate rate);

/// Chooses the rate of every sprite in order (visible ones; others get kNoCells) and lays out
/// the cell store, at most budgetBytes of it and at most maxCellSprites sprites.
CellRatePlan planCellRate(std::span<const SpriteSetup* const> sprites, NearRate rate,
                          std::uint64_t budgetBytes = kDefaultCellBudgetBytes,
                          std::uint64_t maxCellSprites = kMaxCellSprites);
/// The same from each sprite's wish, gathered by the caller (the near passes read them where
/// they write the sprites, so that the plan does not read every sprite's record again).
CellRatePlan planCellRate(std::span<const CellRateWish> wishes,
                          std::uint64_t budgetBytes = kDefaultCellBudgetBytes,
                          std::uint64_t maxCellSprites = kMaxCellSprites);
/// The same into `plan`, whose arrays are reused: a tier that plans every frame keeps one and
/// allocates nothing once it has grown.
void planCellRate(std::span<const CellRateWish> wishes, CellRatePlan& plan,
                  std::uint64_t budgetBytes = kDefaultCellBudgetBytes,
                  std::uint64_t maxCellSprites = kMaxCellSprites);

} // namespace voxtier
