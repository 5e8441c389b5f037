#pragma once
// The figures of a frame (FrameStats) as one table: the name each figure has in every output
// (`voxtier render --csv`, the bench's results.csv and results.json), its unit, how the figures
// of several frames combine, and where the bench report shows it. Everything that lists frame
// figures iterates this table, so adding one is a FrameStats field that the frame fills in
// (compose/frame.cpp) and one line in kFrameFigures.
#include "compose/frame.hpp"

#include <array>
#include <cstddef>
#include <cstdint>
#include <stdexcept>
#include <string>
#include <variant>
#include <vector>

namespace voxtier {

enum class FigureUnit { Count, Bytes, Ms };
const char* toString(FigureUnit u);

/// How the figure of the frames of a camera path becomes one number. Timed repeats of one frame
/// always combine by their median (robust against a loaded machine); the path's frames then
/// combine by this.
enum class AcrossFrames {
    Mean,  ///< per frame, on average (times, work done)
    Sum,   ///< over the whole path
    Worst, ///< the largest frame's (memory held)
};
const char* toString(AcrossFrames a);

using FrameMember =
    std::variant<int FrameStats::*, std::uint64_t FrameStats::*, double FrameStats::*>;

struct FrameFigure {
    const char* name; ///< column name in every CSV and JSON output
    FrameMember member;
    FigureUnit unit;
    AcrossFrames acrossFrames;
    /// A step of the frame: a column of the report's time split of one frame, headed by the name
    /// in words (the steps plus "other" add up to frame_ms).
    bool timeStep = false;

    double of(const FrameStats& s) const {
        return std::visit([&](auto m) { return double(s.*m); }, member);
    }
    /// Stores `v`, truncated toward zero for a count.
    void set(FrameStats& s, double v) const {
        std::visit([&](auto m) { s.*m = std::remove_reference_t<decltype(s.*m)>(v); }, member);
    }
    /// The value as text: integers exactly, milliseconds to the microsecond.
    std::string text(const FrameStats& s) const;
    /// The name in words, without its unit: "near_readback_ms" -> "near readback".
    std::string words() const;
};

/// The table, one line per FrameStats field (kFrameFigures below).
struct FrameFigureTable {
    using enum FigureUnit;
    using enum AcrossFrames;
    static constexpr bool TimeStep = true;
    // clang-format off
    static constexpr FrameFigure lines[] = {
        // name, member, unit, how the frames of a path combine, whether it is a time step
        {"entities",                  &FrameStats::entities,                Count, Mean},
        {"culled",                    &FrameStats::culled,                  Count, Mean},
        {"near_entities",             &FrameStats::nearDrawn,               Count, Mean},
        {"far_entities",              &FrameStats::farDrawn,                Count, Mean},
        {"fading_entities",           &FrameStats::fading,                  Count, Mean},
        {"switches_to_far",           &FrameStats::switchesToFar,           Count, Mean},
        {"switches_to_near",          &FrameStats::switchesToNear,          Count, Mean},
        {"view_changes",              &FrameStats::viewChanges,             Count, Mean},
        {"frame_ms",                  &FrameStats::totalMs,                 Ms,    Mean},
        {"host_setup_ms",             &FrameStats::hostSetupMs,             Ms,    Mean, TimeStep},
        {"host_select_ms",            &FrameStats::hostSelectMs,            Ms,    Mean, TimeStep},
        {"near_ms",                   &FrameStats::nearMs,                  Ms,    Mean, TimeStep},
        {"near_upload_ms",            &FrameStats::nearUploadMs,            Ms,    Mean},
        {"host_record_ms",            &FrameStats::hostRecordMs,            Ms,    Mean},
        {"host_wait_ms",              &FrameStats::hostWaitMs,              Ms,    Mean},
        {"host_readback_ms",          &FrameStats::hostReadbackMs,          Ms,    Mean},
        {"gpu_frame_ms",              &FrameStats::gpuFrameMs,              Ms,    Mean},
        {"gpu_upload_ms",             &FrameStats::gpuUploadMs,             Ms,    Mean},
        {"gpu_cells_ms",              &FrameStats::gpuCellsMs,              Ms,    Mean},
        {"gpu_splat_ms",              &FrameStats::gpuSplatMs,              Ms,    Mean},
        {"gpu_draw_ms",               &FrameStats::gpuDrawMs,               Ms,    Mean},
        {"gpu_resolve_ms",            &FrameStats::gpuResolveMs,            Ms,    Mean},
        {"gpu_far_ms",                &FrameStats::gpuFarMs,                Ms,    Mean},
        {"gpu_copy_ms",               &FrameStats::gpuCopyMs,               Ms,    Mean},
        {"near_cells_traced",         &FrameStats::nearCellsTraced,         Count, Mean},
        {"near_pixels_traced",        &FrameStats::nearPixelsTraced,        Count, Mean},
        {"near_pixels_looked_up",     &FrameStats::nearPixelsLookedUp,      Count, Mean},
        {"near_cell_sprites",         &FrameStats::nearCellSprites,         Count, Mean},
        {"near_cell_over_budget",     &FrameStats::nearCellOverBudget,      Count, Mean},
        {"far_ms",                    &FrameStats::farMs,                   Ms,    Mean},
        {"far_lookup_bake_ms",        &FrameStats::bakeMs,                  Ms,    Mean, TimeStep},
        {"far_blit_ms",               &FrameStats::blitMs,                  Ms,    Mean, TimeStep},
        {"near_fragments",            &FrameStats::nearPixelsTested,        Count, Mean},
        {"near_kernel_fragments",     &FrameStats::nearKernelFragments,     Count, Mean},
        {"voxel_steps",               &FrameStats::voxelFetches,            Count, Mean},
        {"near_bytes_uploaded",       &FrameStats::nearBytesUploaded,       Bytes, Mean},
        {"blit_pixels",               &FrameStats::farPixelsTested,         Count, Mean},
        {"blit_pixels_written",       &FrameStats::farPixelsWritten,        Count, Mean},
        {"far_bakes",                 &FrameStats::farBakes,                Count, Mean},
        {"far_bakes_given_up",        &FrameStats::farBakesGivenUp,         Count, Mean},
        {"far_scenes_built",          &FrameStats::farScenesBuilt,          Count, Mean},
        {"far_refreshes",             &FrameStats::farRefreshes,            Count, Mean},
        {"far_incremental_refreshes", &FrameStats::farIncrementalRefreshes, Count, Mean},
        {"far_cells_retraced",        &FrameStats::farCellsRetraced,        Count, Mean},
        {"rays_traced",               &FrameStats::raysTraced,              Count, Mean},
        {"cache_bytes",               &FrameStats::cacheBytes,              Bytes, Worst},
        {"far_predicted_worst_vpx",   &FrameStats::farPredictedWorstVpx,    Count, Worst},
        {"near_on_vulkan",            &FrameStats::nearOnVulkan,            Count, Mean},
        {"far_on_vulkan",             &FrameStats::farOnVulkan,             Count, Mean},
        {"near_pixels_written",       &FrameStats::nearPixelsWritten,       Count, Mean},
        {"near_occluded",             &FrameStats::nearOccluded,            Count, Mean},
        {"far_occluded",              &FrameStats::farOccluded,             Count, Mean},
        {"near_early_depth_sprites",  &FrameStats::nearEarlyDepthSprites,   Count, Mean},
    };
    // clang-format on
};
inline constexpr const auto& kFrameFigures = FrameFigureTable::lines;
inline constexpr std::size_t kFrameFigureCount = std::size(kFrameFigures);

/// The index of `member`'s line in kFrameFigures: a compile error in a constant expression,
/// std::logic_error otherwise, when it has none.
constexpr std::size_t frameFigureIndex(FrameMember member) {
    for (std::size_t i = 0; i < kFrameFigureCount; ++i)
        if (kFrameFigures[i].member == member) return i;
    throw std::logic_error("a FrameStats member without a line in kFrameFigures");
}

/// Figure by figure, the median over `repeats` (timed repeats of one frame).
FrameStats medianOf(const std::vector<FrameStats>& repeats);

/// One number per figure, in table order: the frames of a path combined as each figure says.
struct PathFigures {
    std::array<double, kFrameFigureCount> values{};
    double of(FrameMember member) const;
};
PathFigures acrossFrames(const std::vector<FrameStats>& frames);

/// "name,name,...", the table's names in order (no newline).
std::string figureCsvHeader();
/// The figures of one frame as CSV fields, in table order (no newline).
std::string figureCsvRow(const FrameStats& s);

} // namespace voxtier
