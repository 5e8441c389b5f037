#pragma once
// `voxtier bench`: speed against error (CONTRACT.md §8). Every measurement is a *configuration*
// (a scene copy, a render mode, selector settings) drawn by its own FrameRenderer; the
// configurations of one *set* run interleaved frame by frame in one process (one shared Vulkan
// device), so the ratios between them see the same machine load:
//
//   pass 0 (warm-up: pipeline compiles, atlas uploads, cold snapshot bakes, recorded separately)
//   passes 1..R (timed): for each sampled path frame, for each configuration: render (the
//   non-truth configurations in an order rotated by one place per pass)
//
// The selector state restarts with each pass (a pass is the camera path from its start). Times
// are medians over the R passes, per frame, then averaged over the path frames. In the last pass
// every approximate image is compared with the all-near (Vulkan) image of the same frame.
#include "compose/frame.hpp"
#include "compose/frame_error.hpp"
#include "compose/frame_figures.hpp"
#include "core/scene.hpp"

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

namespace voxtier::bench {

/// The ways the bench draws a scene. Adding one is a line in kBenchModes (and what it sets in
/// FrameOptions, apps/bench/suite.cpp runSet).
enum class BenchMode { NearVulkan, NearVulkanFragment, NearReference, Far, Hybrid, HybridGpuFar };

struct BenchModeInfo {
    BenchMode mode;
    const char* name; ///< in results.csv, results.json and the report
    RenderMode renderMode;
    NearBackend nearBackend; ///< who draws the near tier (where the render mode leaves it open)
    /// Who draws the far tier: Auto = the suite's --far-backend (cpu by default); hybrid_gpu_far
    /// is the Vulkan far pass beside the hybrid, with the same near backend.
    FarBackend farBackend;
    /// Per-pixel tracing everywhere (the seed's single fragment pass, the baseline of cell-rate
    /// sprites); otherwise the suite's --near-rate (auto by default).
    bool perPixel;
    /// The ground truth: every other mode's error is measured against this mode's image.
    bool isTruth;
    /// Near tier on Vulkan: its voxel reads are counted in an extra, untimed frame (the counting
    /// shader is slower), and its steps per second are taken over the near draw time.
    bool countsStepsApart;
};

// clang-format off
inline constexpr BenchModeInfo kBenchModes[] = {
    // mode                         name                    render mode            near backend            far backend          per pixel truth  counts steps apart
    {BenchMode::NearVulkan,         "near_vulkan",          RenderMode::Near,      NearBackend::Vulkan,    FarBackend::Cpu,     false,    true,  true},
    {BenchMode::NearVulkanFragment, "near_vulkan_fragment", RenderMode::Near,      NearBackend::Vulkan,    FarBackend::Cpu,     true,     false, false},
    {BenchMode::NearReference,      "near_reference",       RenderMode::Reference, NearBackend::Reference, FarBackend::Cpu,     false,    false, false},
    {BenchMode::Far,                "far",                  RenderMode::Far,       NearBackend::Reference, FarBackend::Auto,    false,    false, false},
    {BenchMode::Hybrid,             "hybrid",               RenderMode::Hybrid,    NearBackend::Auto,      FarBackend::Auto,    false,    false, false},
    {BenchMode::HybridGpuFar,       "hybrid_gpu_far",       RenderMode::Hybrid,    NearBackend::Auto,      FarBackend::Vulkan,  false,    false, false},
};
// clang-format on
const BenchModeInfo& info(BenchMode mode);
const char* toString(BenchMode mode);

/// "x3": a snapshot scale's name in the sweep settings, the report and the plots (the far tier
/// reads snapshots baked at that multiple of the sprite's sigma, SelectorConfig::snapshotScale).
std::string scaleName(int snapshotScale);

struct SuiteOptions {
    std::vector<std::string>
        scenes; ///< scene files; the first also gets the sweeps and scaling curves
    std::string out = "out/bench";
    bool quick = false;
    bool smoke = false;  ///< test-only: tiny scenes, one repeat, one sweep point
    int repeats = -1;    ///< -1: the preset's
    int warmup = -1;     ///< -1: the preset's (at least 1: the cold bakes are measured there)
    int pathFrames = -1; ///< -1: the preset's
    int motionFrames = -1, motionWarmup = -1; ///< -1: the preset's
    std::string size; ///< WxH override of every scene's image size ("" = the scene's)
    bool sweeps = true, scaling = true;
    std::string entityCounts, modelSides; ///< comma-separated overrides of the scaling points
    std::string snapshotScales; ///< "1,3": override of the error_budget sweep's snapshot scales
    std::string cacheDir;       ///< on-disk snapshot cache of every configuration ("" = none)
    std::uint64_t cacheDirBytes = 0;             ///< its size limit (0 = none)
    NearRate nearRate = NearRate::Auto;          ///< of every mode but near_vulkan_fragment
    FarBlitKernel farBlit = FarBlitKernel::Simd; ///< of every mode
    /// Who draws the far tier of the rows whose table entry says Auto (hybrid, far and the
    /// sweeps); hybrid_gpu_far is always the Vulkan far pass. Cpu by default, so the CPU-blit
    /// hybrid stands beside hybrid_gpu_far on every machine.
    FarBackend farBackend = FarBackend::Cpu;
    /// Of every mode: FrameOptions::occlusionCull (--cull) and earlyDepthTest (--no-cull: off).
    bool occlusionCull = false;
    bool earlyDepthTest = true;
    /// The error budget's cost bound on bakes (--no-cost-bound: off, so that every scale's
    /// error is measured on the same plan, whatever its blit costs).
    bool costBound = true;
    /// Every scene's selector becomes the error budget at this many virtual pixels (its view set,
    /// view hysteresis and cross-fade kept); unset: each scene's own selector.
    std::optional<double> budgetVpx;
};

/// The resolved plan (preset + overrides).
struct Plan {
    std::string preset; ///< "full", "quick" or "smoke"
    int repeats = 7, warmup = 1, pathFrames = 6;
    /// In motion: the path's first motionFrames frames in order, each timed once with its bakes;
    /// the first motionWarmup of them are the cold start (0 frames: no in-motion run).
    int motionFrames = 48, motionWarmup = 6;
    std::optional<int> width, height;
    std::optional<int> entityCap; ///< scenes are cut to their first N entities (smoke)
    bool sweeps = true, scaling = true;
    std::vector<double> distanceFarAt, radiusFarAt, errorFarAt; ///< selector sweeps
    std::vector<int> viewSets, crossfades;
    std::vector<double> budgets; ///< error_budget sweep (virtual pixels)
    /// The snapshot scales the error_budget sweep runs each budget with (the speed–error
    /// frontier: one curve per scale); the first is the one the budget target reads.
    std::vector<int> snapshotScales;
    std::vector<int> ladderCaps; ///< error_budget sweep at 1 vpx
    std::vector<double> sigmas;
    std::vector<int> entityCounts, modelSides;
    int sizeEntities = 500; ///< entities of the model-size curve
    int scalingRepeats = 5;
    std::string cacheDir; ///< SuiteOptions::cacheDir
    std::uint64_t cacheDirBytes = 0;
    NearRate nearRate = NearRate::Auto;          ///< SuiteOptions::nearRate
    std::optional<double> budgetVpx;             ///< SuiteOptions::budgetVpx
    FarBlitKernel farBlit = FarBlitKernel::Simd; ///< SuiteOptions::farBlit
    FarBackend farBackend = FarBackend::Cpu;     ///< SuiteOptions::farBackend
    bool occlusionCull = false;                  ///< SuiteOptions::occlusionCull
    bool earlyDepthTest = true;                  ///< SuiteOptions::earlyDepthTest
    bool costBound = true;                       ///< SuiteOptions::costBound
};

/// One sampled path frame of a measured configuration.
struct FrameRow {
    int frame = 0;
    double time = 0.0;
    /// Figure by figure, the median over the timed passes (kFrameFigures); where the mode counts
    /// voxel reads apart (countsStepsApart), voxelFetches and nearKernelFragments are the
    /// counting frame's.
    FrameStats median;
    double minMs = 0.0, maxMs = 0.0; ///< spread of totalMs over the passes
    bool hasError = false;
    FrameErrorReport error; ///< against the all-near (Vulkan) image of the frame (last pass)
};

/// One measured configuration, aggregated over the sampled path frames.
struct Measurement {
    std::string group; ///< "modes", "sweep", "scaling_entities", "scaling_size"
    std::string scene; ///< scene name (file stem)
    BenchMode mode = BenchMode::NearVulkan;
    std::string family;   ///< sweep family ("" outside sweeps)
    std::string setting;  ///< human-readable settings of the configuration
    double param = 0.0;   ///< the swept / scaled value
    std::string selector; ///< selector summary, e.g. "error_px 1/0.5, 26 views, sigma 1, fade 0"
    std::string truth;    ///< configuration the errors are measured against
    std::vector<FrameRow> frames;

    /// The frames' figures (FrameRow::median) combined over the path as kFrameFigures says.
    PathFigures figures;
    double frameMs() const { return figures.of(&FrameStats::totalMs); }
    double visible = 0;      ///< entities - culled, per frame
    double worstFrameMs = 0; ///< the slowest path frame's median
    double baselineMs = 0;   ///< all-near (Vulkan) of the same frames, same run
    double speedup = 0;      ///< baselineMs / frameMs()
    /// near_vulkan_fragment (per-pixel everywhere) of the same frames, same run, and the speed-up
    /// against it: what cell-rate sprites buy.
    double fragmentMs = 0, speedupVsFragment = 0;
    /// Near fragments of the all-near (Vulkan) frames: near_fragments / this = the near share.
    double baselineFragments = 0;
    // Throughput.
    double voxelStepsPerS = 0;   ///< near voxel reads over the near time (draw time on Vulkan)
    double blitPixelsPerS = 0;   ///< footprint pixels the blit evaluated over the blit time
    double memcpyPixelsPerS = 0; ///< memcpy of the same bytes
    // In motion: consecutive path frames from an empty cache, each timed once.
    double motionMs = 0; ///< median frame ms after the cold start
    /// The same frames' mean, 90th percentile and worst: bakes come in bursts (an animation
    /// step asks for new snapshots at once), so the median alone can hide or exaggerate them.
    double motionMeanMs = 0, motionP90Ms = 0, motionWorstMs = 0;
    double motionColdMs = 0;                        ///< mean frame ms of the cold-start frames
    double motionBaselineMs = 0, motionSpeedup = 0; ///< all-near (Vulkan) in motion, its ratio
    /// The CPU reference all-near (near_reference) in motion, same frames, same run, and the
    /// ratio: the fastest exact path a machine without a GPU has.
    double motionReferenceMs = 0, motionSpeedupVsReference = 0;
    /// The faster of those two exact paths in motion, and the ratio (the speed–error frontier's
    /// x axis).
    double motionFastestExactMs = 0, motionSpeedupVsFastestExact = 0;
    /// Who drew the near tier: "vulkan" or "reference" (what --near-backend auto chose, for the
    /// hybrid).
    std::string nearBackend;
    /// Who drew the far tier: "cpu" or "vulkan" ("" where the mode draws no far sprite).
    std::string farBackend;
    /// The far tier's snapshots' scale over the sprite's sigma (0 where the mode draws no far
    /// sprite).
    int snapshotScale = 0;
    double motionBakes = 0, motionBakeMs = 0; ///< per frame after the cold start (mean)
    double motionCacheBytes = 0; ///< snapshot bytes held, the most over the in-motion frames
    /// The near tier's ms and the entities each tier drew, per frame after the cold start
    /// (means): what the entities drawn near cost even if far sprites were free.
    double motionNearMs = 0, motionNearEntities = 0, motionFarEntities = 0;
    double motionPsnrMin = 0; ///< against the all-near frame of the same motion frame
    /// That worst frame's differing share, differing pixels and far sprites: how far its error
    /// is from a PSNR target follows from them (bench report, "target and bound").
    double motionPsnrMinShare = 0, motionPsnrMinPixels = 0, motionPsnrMinFar = 0;
    double motionDifferingShare = 0;    ///< of the frame's pixels, mean (colour, depth or id)
    double motionPredictedWorstVpx = 0; ///< FrameStats::farPredictedWorstVpx, worst frame
    // Cold (the warm-up pass, first use of every snapshot).
    double coldMs = 0, coldBakeMs = 0, coldBakes = 0, coldRays = 0, raysPerS = 0;
    // Error against the truth (means / worst over the frames).
    bool hasError = false;
    double mismatchMean = 0, mismatchWorst = 0; ///< visible footprints in the frame, every entity
    double farMismatchMean = 0;                 ///< the same over the far-drawn entities
    /// Far-drawn entities drawn alone by both tiers (no occlusion): mean mismatch, worst
    /// silhouette displacement in screen and virtual pixels.
    double farIsolatedMismatchMean = 0, displacementWorstPx = 0, displacementWorstCells = 0;
    double farVisibleDisplacementWorstPx = 0; ///< in the frame (occluders' changes included)
    double coverageMismatchMean = 0; ///< like mismatchMean, counting only pixels owned in one image
    double farAloneEntities = 0,
           farOverOneCell = 0; ///< per frame (mean): far entities, those displaced > 1 virtual px
    double rmseMean = 0, psnrMin = 0;
    double differingPixels = 0; ///< mean per frame (colour, depth or id)
    std::size_t missing = 0;    ///< entities drawn in only one image, summed over frames
};

/// The sweep family of the error budget; the report's budget section reads it.
inline constexpr const char* kBudgetFamily = "budget (error_budget)";

struct SuiteResults {
    Plan plan;
    std::vector<std::string> scenes;
    std::string vulkanDevice, cpu;
    unsigned threads = 0;
    double wallSeconds = 0;
    double memcpyGBps = 0; ///< the bandwidth of the memcpy references, for the report
    std::vector<Measurement> rows;
    std::vector<std::string> notes; ///< things the reader must know (skipped parts, caveats)
};

/// Bytes per blitted pixel the memcpy reference copies: the target's colour, depth and id.
constexpr double kBlitBytesPerPixel = 12.0;

Plan makePlan(const SuiteOptions& options);
SuiteResults runSuite(const SuiteOptions& options);

} // namespace voxtier::bench
