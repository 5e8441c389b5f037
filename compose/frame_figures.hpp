#pragma once
// The figures of a frame as one table: the name each figure has in every output (`voxtier render
// --csv`, the bench's results.csv and results.json), where in FrameStats it comes from, its unit,
// how the figures of several frames combine, and where the bench report shows it. Everything
// that lists frame figures iterates this table, so adding one is a field the frame or a backend
// fills in and one line in kFrameFigures. Code reads a figure by its output name
// (Figures::operator[]("frame_ms")), checked at compile time: grep a column, find its readers.
#include "compose/frame.hpp"

#include <array>
#include <cstddef>
#include <cstdint>
#include <stdexcept>
#include <string>
#include <string_view>
#include <vector>

namespace voxtier {

enum class FigureUnit {
    Count,
    Bytes,
    Ms,
    Vpx, ///< virtual pixels (CONTRACT.md §5)
};
const char* toString(FigureUnit u);
/// Counts and bytes are whole numbers: printed exactly, and their medians truncated.
constexpr bool isWhole(FigureUnit u) {
    return u == FigureUnit::Count || u == FigureUnit::Bytes;
}

/// How the figure of the frames of a camera path becomes one number. Timed repeats of one frame
/// always combine by their median (robust against a loaded machine); the path's frames then
/// combine by this.
enum class AcrossFrames {
    Mean,  ///< per frame, on average (times, work done)
    Sum,   ///< over the whole path
    Worst, ///< the largest frame's (memory held)
};
const char* toString(AcrossFrames a);

struct FrameFigure {
    const char* name; ///< column name in every CSV and JSON output
    double (*read)(const FrameStats&);
    FigureUnit unit;
    AcrossFrames acrossFrames;
    /// A step of the frame: a column of the report's time split of one frame, headed by the name
    /// in words (the steps plus "other" add up to frame_ms).
    bool timeStep = false;

    /// The value as text: whole numbers exactly, the rest to three decimals (ms: the microsecond).
    std::string text(double value) const;
    /// The name in words, without its unit: "near_readback_ms" -> "near readback".
    std::string words() const;
};

/// The table, one line per output column (kFrameFigures below). A column that two backends fill
/// adds them: a frame draws its near sprites with one near backend and its far ones with one far
/// backend, so the other's share is zero.
struct FrameFigureTable {
    using enum FigureUnit;
    using enum AcrossFrames;
    using S = FrameStats;
    static constexpr bool TimeStep = true;
    // clang-format off
    static constexpr FrameFigure lines[] = {
        // name, what it reads, unit, how the frames of a path combine, whether it is a time step
        {"entities",                  [](const S& s) { return double(s.entities); },                Count, Mean},
        {"culled",                    [](const S& s) { return double(s.culled); },                  Count, Mean},
        {"near_entities",             [](const S& s) { return double(s.nearDrawn); },               Count, Mean},
        {"far_entities",              [](const S& s) { return double(s.farDrawn); },                Count, Mean},
        {"fading_entities",           [](const S& s) { return double(s.plan.fading); },             Count, Mean},
        {"switches_to_far",           [](const S& s) { return double(s.plan.switchesToFar); },      Count, Mean},
        {"switches_to_near",          [](const S& s) { return double(s.plan.switchesToNear); },     Count, Mean},
        {"view_changes",              [](const S& s) { return double(s.plan.viewChanges); },        Count, Mean},
        {"frame_ms",                  [](const S& s) { return s.totalMs; },                         Ms,    Mean},
        {"host_setup_ms",             [](const S& s) { return s.hostSetupMs; },                     Ms,    Mean, TimeStep},
        {"host_select_ms",            [](const S& s) { return s.hostSelectMs; },                    Ms,    Mean, TimeStep},
        {"host_select_inputs_ms",     [](const S& s) { return s.plan.ms.inputs; },                  Ms,    Mean},
        {"host_select_tiers_ms",      [](const S& s) { return s.plan.ms.tiers; },                   Ms,    Mean},
        {"host_select_views_ms",      [](const S& s) { return s.plan.ms.views; },                   Ms,    Mean},
        {"host_select_choices_ms",    [](const S& s) { return s.plan.ms.choices; },                 Ms,    Mean},
        {"host_select_cost_bound_ms", [](const S& s) { return s.plan.ms.costBound; },               Ms,    Mean},
        {"host_select_predictions_ms",[](const S& s) { return s.plan.ms.predictions; },             Ms,    Mean},
        {"near_ms",                   [](const S& s) { return s.nearMs; },                          Ms,    Mean, TimeStep},
        {"near_upload_ms",            [](const S& s) { return s.vulkanNear.uploadMs; },             Ms,    Mean},
        {"host_record_ms",            [](const S& s) { return s.vulkan.hostRecordMs; },             Ms,    Mean},
        {"host_record_sprites_ms",    [](const S& s) { return s.vulkanNear.recordSpritesMs; },      Ms,    Mean},
        {"host_record_lists_ms",      [](const S& s) { return s.vulkanNear.recordListsMs; },        Ms,    Mean},
        {"host_record_lists_build_ms",[](const S& s) { return s.vulkanNear.recordListsBuildMs; },   Ms,    Mean},
        {"host_record_lists_upload_ms",[](const S& s) { return s.vulkanNear.recordListsUploadMs; }, Ms,    Mean},
        {"host_record_order_ms",      [](const S& s) { return s.vulkanNear.recordOrderMs; },        Ms,    Mean},
        {"host_record_residency_ms",  [](const S& s) { return s.vulkanNear.recordResidencyMs; },    Ms,    Mean},
        {"host_record_far_ms",        [](const S& s) { return s.vulkan.hostRecordFarMs; },         Ms,    Mean},
        {"host_wait_ms",              [](const S& s) { return s.vulkan.hostWaitMs; },               Ms,    Mean},
        {"host_readback_ms",          [](const S& s) { return s.vulkan.hostReadbackMs; },           Ms,    Mean},
        {"gpu_frame_ms",              [](const S& s) { return s.vulkan.gpuFrameMs; },               Ms,    Mean},
        {"gpu_upload_ms",             [](const S& s) { return s.vulkan.gpuUploadMs; },              Ms,    Mean},
        {"gpu_cells_ms",              [](const S& s) { return s.vulkan.gpuCellsMs; },               Ms,    Mean},
        {"gpu_splat_ms",              [](const S& s) { return s.vulkan.gpuSplatMs; },               Ms,    Mean},
        {"gpu_draw_ms",               [](const S& s) { return s.vulkan.gpuDrawMs; },                Ms,    Mean},
        {"gpu_resolve_ms",            [](const S& s) { return s.vulkan.gpuResolveMs; },             Ms,    Mean},
        {"gpu_far_ms",                [](const S& s) { return s.vulkan.gpuFarMs; },                 Ms,    Mean},
        {"gpu_copy_ms",               [](const S& s) { return s.vulkan.gpuCopyMs; },                Ms,    Mean},
        {"near_cells_traced",         [](const S& s) { return double(s.reference.cellsTraced + s.vulkanNear.cellsTraced); },       Count, Mean},
        {"near_pixels_traced",        [](const S& s) { return double(s.reference.pixelsTraced + s.vulkanNear.pixelsTraced); },     Count, Mean},
        {"near_pixels_looked_up",     [](const S& s) { return double(s.reference.pixelsLookedUp + s.vulkanNear.pixelsLookedUp); }, Count, Mean},
        {"near_cell_sprites",         [](const S& s) { return double(s.reference.cellSprites + s.vulkanNear.cellSprites); },       Count, Mean},
        {"near_cell_over_budget",     [](const S& s) { return double(s.reference.cellOverBudget + s.vulkanNear.cellOverBudget); }, Count, Mean},
        {"far_ms",                    [](const S& s) { return s.farMs; },                           Ms,    Mean},
        {"far_lookup_bake_ms",        [](const S& s) { return s.far.ensureMs; },                    Ms,    Mean, TimeStep},
        {"far_blit_ms",               [](const S& s) { return s.far.blit.milliseconds + s.vulkan.farPassMs; }, Ms, Mean, TimeStep},
        {"far_snapshot_upload_ms",    [](const S& s) { return s.vulkan.farSnapshotsMs; },           Ms,    Mean},
        {"near_fragments",            [](const S& s) { return double(s.reference.pixelsTested + s.vulkanNear.fragmentInvocations); }, Count, Mean},
        {"near_kernel_fragments",     [](const S& s) { return double(s.vulkanNear.kernelFragments); }, Count, Mean},
        {"voxel_steps",               [](const S& s) { return double(s.reference.voxelFetches + s.vulkanNear.voxelFetches); },     Count, Mean},
        {"near_bytes_uploaded",       [](const S& s) { return double(s.vulkanNear.bytesUploaded); }, Bytes, Mean},
        {"far_bytes_uploaded",        [](const S& s) { return double(s.vulkanFar.bytesUploaded); }, Bytes, Mean},
        {"blit_pixels",               [](const S& s) { return double(s.far.blit.pixelsTested); },   Count, Mean},
        {"blit_pixels_written",       [](const S& s) { return double(s.far.blit.pixelsWritten); },  Count, Mean},
        {"far_bakes",                 [](const S& s) { return double(s.far.bakes); },               Count, Mean},
        {"far_bakes_given_up",        [](const S& s) { return double(s.plan.bakesGivenUp); },       Count, Mean},
        {"far_held_near",             [](const S& s) { return double(s.plan.heldNear); },           Count, Mean},
        {"far_paused_near",           [](const S& s) { return double(s.plan.pausedNear); },         Count, Mean},
        {"cache_questions",           [](const S& s) { return double(s.plan.cacheQuestions); },     Count, Mean},
        {"far_scenes_built",          [](const S& s) { return double(s.far.scenesBuilt); },         Count, Mean},
        {"far_refreshes",             [](const S& s) { return double(s.far.refreshes); },           Count, Mean},
        {"far_incremental_refreshes", [](const S& s) { return double(s.far.incrementalRefreshes); }, Count, Mean},
        {"far_cells_retraced",        [](const S& s) { return double(s.far.cellsRetraced); },       Count, Mean},
        {"rays_traced",               [](const S& s) { return double(s.far.raysTraced); },          Count, Mean},
        {"cache_bytes",               [](const S& s) { return double(s.cacheBytes); },              Bytes, Worst},
        {"far_predicted_worst_vpx",   [](const S& s) { return s.plan.worstVpx; },                   Vpx,   Worst},
        {"near_on_vulkan",            [](const S& s) { return double(s.nearOnVulkan); },            Count, Mean},
        {"far_on_vulkan",             [](const S& s) { return double(s.farOnVulkan); },             Count, Mean},
        {"near_pixels_written",       [](const S& s) { return double(s.reference.pixelsWritten); }, Count, Mean},
        {"near_occluded",             [](const S& s) { return double(s.reference.culled); },        Count, Mean},
        {"far_occluded",              [](const S& s) { return double(s.far.culled); },              Count, Mean},
        {"near_early_depth_sprites",  [](const S& s) { return double(s.vulkanNear.earlyDepthSprites); }, Count, Mean},
    };
    // clang-format on
};
inline constexpr const auto& kFrameFigures = FrameFigureTable::lines;
inline constexpr std::size_t kFrameFigureCount = std::size(kFrameFigures);

/// A figure by its output name, looked up at compile time: a name with no line in kFrameFigures
/// does not compile.
struct FigureId {
    std::size_t index;
    consteval FigureId(const char* name) : index(find(name)) {}
    static constexpr std::size_t find(std::string_view name) {
        for (std::size_t i = 0; i < kFrameFigureCount; ++i)
            if (kFrameFigures[i].name == name) return i;
        throw std::logic_error("no line in kFrameFigures has this name");
    }
    const FrameFigure& figure() const { return kFrameFigures[index]; }
};

/// One number per figure, in table order: one frame's, the median of a frame's timed repeats, or
/// the frames of a path combined.
struct Figures {
    std::array<double, kFrameFigureCount> values{};
    double operator[](FigureId id) const { return values[id.index]; }
    double& operator[](FigureId id) { return values[id.index]; }
};
/// The figures of one frame, read through the table.
Figures figuresOf(const FrameStats& s);
/// Figure by figure, the median over `repeats` (timed repeats of one frame); whole-number
/// figures truncated toward zero (isWhole).
Figures medianOf(const std::vector<FrameStats>& repeats);
/// The frames of a path combined, figure by figure, as each figure's acrossFrames says.
Figures acrossFrames(const std::vector<Figures>& frames);

/// "name,name,...", the table's names in order (no newline).
std::string figureCsvHeader();
/// Figures as CSV fields, in table order (no newline).
std::string figureCsvRow(const Figures& f);

} // namespace voxtier
