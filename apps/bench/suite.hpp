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

/// How much a run measures: a row of the preset table (apps/bench/presets.cpp), and, with the
/// command line's overrides applied, the most of a Plan.
struct Preset {
    std::string name;      ///< "full", "quick" or "smoke"
    bool testOnly = false; ///< not offered in --help (smoke)
    int repeats = 7;       ///< timed passes per sampled path frame
    int warmup = 1;        ///< untimed passes first (the cold bakes are measured in the first)
    int pathFrames = 6;    ///< path frames sampled per scene
    /// In motion: the path's first motionFrames frames in order, each timed once with its bakes;
    /// the first motionWarmup of them are the cold start.
    int motionFrames = 48, motionWarmup = 6;
    std::optional<int> width, height; ///< every scene's image size (unset: each scene's)
    std::optional<int> entityCap;     ///< scenes are cut to their first N entities
    bool sweeps = true, scaling = true;
    std::vector<double> distanceFarAt, radiusFarAt, errorFarAt; ///< selector sweeps
    std::vector<int> viewSets, crossfades;
    std::vector<double> budgets; ///< error_budget sweep (virtual pixels)
    /// The snapshot scales the error_budget sweep runs each budget with (the speed–error
    /// frontier: one curve per scale); the first is the one the budget target reads.
    std::vector<int> snapshotScales;
    std::vector<int> ladderCaps; ///< error_budget sweep at 1 vpx
    std::vector<double> sigmas;
    std::vector<int> entityCounts, modelSides; ///< the scaling curves' points
    int sizeEntities = 500;                    ///< entities of the model-size curve
    int scalingRepeats = 5;                    ///< timed passes per scaling point
};

/// The base every configuration draws from: the flags `bench` shares with `render`
/// (apps/cli_options.hpp addFrameFlags) and --cache-dir. Each mode then sets its own backends
/// and near rate (kBenchModes, apps/bench/suite.cpp frameOptions). The far tier is the CPU blit
/// unless --far-backend says otherwise, so the CPU-blit hybrid stands beside hybrid_gpu_far on
/// every machine.
FrameOptions benchFrameOptions();

struct SuiteOptions {
    /// Scene files; the first also gets the sweeps and scaling curves.
    std::vector<std::string> scenes;
    std::string out = "out/bench";
    std::string preset = "full"; ///< a name in the preset table (--quick, --smoke)
    /// Overrides of the preset's figures, unset or empty where the preset's stand (the table
    /// in apps/bench/presets.hpp names their flags and bounds).
    std::optional<int> repeats, warmup, pathFrames, motionFrames, motionWarmup;
    std::string size;                                     ///< WxH: every scene's image size
    std::string entityCounts, modelSides, snapshotScales; ///< "a,b,c"
    bool sweeps = true, scaling = true;
    FrameOptions frame = benchFrameOptions();
    /// Every scene's selector becomes the error budget at this many virtual pixels (its view set,
    /// view hysteresis, cross-fade and snapshot scale kept); unset: each scene's own selector.
    std::optional<double> budgetVpx;
};

/// The resolved plan: the preset with the overrides (makePlan, apps/bench/presets.hpp), and
/// how every configuration draws.
struct Plan : Preset {
    FrameOptions frame;              ///< SuiteOptions::frame
    std::optional<double> budgetVpx; ///< SuiteOptions::budgetVpx
};

/// One sampled path frame of a measured configuration.
struct FrameRow {
    int frame = 0;
    double time = 0.0;
    /// Figure by figure, the median over the timed passes (kFrameFigures); where the mode counts
    /// voxel reads apart (countsStepsApart), voxelFetches and nearKernelFragments are the
    /// counting frame's.
    Figures median;
    double minMs = 0.0, maxMs = 0.0; ///< spread of totalMs over the passes
    bool hasError = false;
    FrameErrorReport error; ///< against the all-near (Vulkan) image of the frame (last pass)
};

/// In motion (issue 13): consecutive path frames from an empty cache, each timed once. Figures
/// are over the frames after the cold start (medians, or means where said) unless said.
struct InMotion {
    double ms = 0; ///< median frame ms
    /// The same frames' mean, 90th percentile and worst: bakes come in bursts (an animation
    /// step asks for new snapshots at once), so the median alone can hide or exaggerate them.
    double meanMs = 0, p90Ms = 0, worstMs = 0;
    double coldMs = 0; ///< mean frame ms of the cold-start frames
    /// The exact all-near paths of the same frames in the same run, and the speed-ups against
    /// them: the Vulkan near tier (the truth), the CPU reference (the fastest exact path a
    /// machine without a GPU has, issue 24), and the faster of the two.
    double allNearVulkanMs = 0, speedupVsAllNearVulkan = 0;
    double allNearReferenceMs = 0, speedupVsAllNearReference = 0;
    double fastestExactMs = 0, speedupVsFastestExact = 0;
    double bakes = 0, bakeMs = 0; ///< per frame (means)
    double cacheBytes = 0;        ///< snapshot bytes held, the most over all the frames
    /// The near tier's ms and the entities each tier drew, per frame (means): what the entities
    /// drawn near cost even if far sprites were free.
    double nearMs = 0, nearEntities = 0, farEntities = 0;
    /// The lowest frame PSNR against the all-near frame of the same motion frame (cold start
    /// included), and that frame's differing share, differing pixels and far sprites: how far
    /// its error is from a PSNR target follows from them (bench report, "target and bound").
    double psnrMin = 0, psnrMinShare = 0, psnrMinDifferingPixels = 0, psnrMinFarEntities = 0;
    double differingShare = 0;    ///< of the frame's pixels, mean (colour, depth or id)
    double predictedWorstVpx = 0; ///< "far_predicted_worst_vpx", worst frame
    /// The same timed frames' figures combined as kFrameFigures says (times: per frame, on
    /// average): where an in-motion frame's time goes, its time steps, host parts and device
    /// passes (results.csv's in_motion_mean_*_ms columns, the report's in-motion split). Means,
    /// not medians: bakes come every few frames (an animation step), and the medians of bursty
    /// parts do not add up to the frame; the means add up to in_motion_mean_ms. The warm frame's
    /// split (Measurement::figures) is a frame whose snapshots are all there: under an error
    /// budget its bakes, view changes and selection are not a moving frame's.
    Figures split;
};

/// Cold: the warm-up pass, the first use of every snapshot.
struct Cold {
    double firstFrameMs = 0;
    double bakeMs = 0, bakes = 0, rays = 0; ///< over the pass
    double raysPerS = 0;                    ///< Embree rays of its bakes over their wall time
};

/// The error against the truth on the sampled frames: means (per frame) or worsts.
struct PathError {
    double mismatchMean = 0, mismatchWorst = 0; ///< visible footprints in the frame, every entity
    double coverageMismatchMean = 0; ///< like mismatchMean, counting only pixels owned in one image
    double farMismatchMean = 0;      ///< the same over the far-drawn entities
    /// Far-drawn entities drawn alone by both tiers (no occlusion): how many, mean mismatch,
    /// worst silhouette displacement in screen and virtual pixels, and how many are displaced by
    /// more than one virtual pixel.
    double farAloneEntities = 0, farAloneMismatchMean = 0;
    double farDisplacementWorstPx = 0, farDisplacementWorstVpx = 0;
    double farDisplacedOver1Vpx = 0;
    double farVisibleDisplacementWorstPx = 0; ///< in the frame (occluders' changes included)
    double rmseMean = 0, psnrMin = 0;
    double differingPixels = 0;      ///< colour, depth or id
    std::size_t missingEntities = 0; ///< drawn in only one image, summed over the frames
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
    double imagePixels = 0; ///< of one frame

    /// The frames' figures (FrameRow::median) combined over the path as kFrameFigures says.
    Figures figures;
    double frameMs() const { return figures["frame_ms"]; }
    double visible = 0;      ///< entities - culled, per frame
    double worstFrameMs = 0; ///< the slowest path frame's median
    /// The same frames drawn on the Vulkan device alone and not read back (FrameOptions::
    /// readBack): frame ms as frameMs() takes it (medians over the passes, mean over the path
    /// frames), what a frame shown on the GPU costs. 0 where a CPU tier draws part of the frame.
    double deviceFrameMs = 0;
    /// The exact paths of the same frames in the same run, at the same sigma (0 where not
    /// measured), and the speed-ups against them: all-near on Vulkan (the truth), per-pixel near
    /// sprites on Vulkan (what cell-rate sprites buy), and the fastest exact path (the faster of
    /// all-near on Vulkan and on the CPU reference).
    double allNearVulkanMs = 0, speedupVsAllNearVulkan = 0;
    double nearVulkanFragmentMs = 0, speedupVsNearVulkanFragment = 0;
    double fastestExactMs = 0, speedupVsFastestExact = 0;
    std::string fastestExact; ///< which mode that was ("" where not measured)
    /// Near fragments of the all-near (Vulkan) frames.
    double allNearVulkanFragments = 0;
    /// Near fragments of the all-near frames drawn by the same near backend at the same rate and
    /// sigma (0 where not measured): near_fragments over this is the share of the near work the
    /// configuration still does.
    double allNearSameBackendFragments = 0;
    // Throughput.
    double voxelStepsPerS = 0;   ///< near voxel reads over the near time (draw time on Vulkan)
    double blitPixelsPerS = 0;   ///< footprint pixels the blit evaluated over the blit time
    double memcpyPixelsPerS = 0; ///< memcpy of the same bytes
    /// Who drew the near tier: "vulkan" or "reference" (what --near-backend auto chose, for the
    /// hybrid).
    std::string nearBackend;
    /// Who drew the far tier: "cpu" or "vulkan" ("" where the mode draws no far sprite).
    std::string farBackend;
    /// The far tier's snapshots' scale over the sprite's sigma (0 where the mode draws no far
    /// sprite).
    int snapshotScale = 0;
    InMotion motion;
    Cold cold;
    bool hasError = false; ///< false for the truth
    PathError error;
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

/// Measures everything `options` asks for (makePlan's errors first, before any work).
SuiteResults runSuite(const SuiteOptions& options);

} // namespace voxtier::bench
