#pragma once
// The frame recipe of DESIGN.md §6: select tiers -> draw near sprites (Vulkan) -> ensure the
// snapshots far sprites need (lazy, parallel) -> blit far sprites -> compose by min-z (with
// FarBackend::Vulkan, one Vulkan frame draws the near sprites and then the far ones). compose/
// draws and composes; the selection, its views and the bakes it can afford are lod/'s
// (lod/frame_planner.hpp). A FrameRenderer keeps what persists between frames of one scene: the
// planner (the selector's per-entity state, the budget's views, the measured costs), the
// snapshot cache and the Vulkan device with its voxel atlas.
#include "compose/pop_measure.hpp"
#include "core/image.hpp"
#include "core/scene.hpp"
#include "core/sprite.hpp"
#include "core/view_set.hpp"
#include "core/work_progress.hpp"
#include "device/vulkan_options.hpp"
#include "impostor_cache/far_blit.hpp"
#include "lod/frame_planner.hpp"
#include "lod/selector.hpp"
#include "volumetric/near_rate.hpp"

#include <array>
#include <cstddef>
#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <utility>
#include <vector>

namespace voxtier {

class NearRenderer;
class SnapshotCache;
struct FarRequest;
struct FarBatch;

enum class RenderMode {
    Reference, ///< every entity through the CPU reference tracer (the executable spec)
    Near,      ///< every entity through the Vulkan near tier (volumetric/near_renderer.hpp)
    Far,       ///< every entity through the far tier's snapshot cache (DESIGN.md §4)
    Hybrid,    ///< the selector decides per entity (DESIGN.md §5): the product's main job
};
/// The one table of render mode names (command line, console, reports), in the order `--help`
/// lists them: parseRenderMode, toString and the CLI's --mode all read it.
inline constexpr std::array<std::pair<const char*, RenderMode>, 4> kRenderModeNames{{
    {"hybrid", RenderMode::Hybrid},
    {"near", RenderMode::Near},
    {"far", RenderMode::Far},
    {"reference", RenderMode::Reference},
}};
RenderMode parseRenderMode(const std::string& name); ///< throws InputError(field "--mode")
const char* toString(RenderMode m);

/// Who draws the near tier. Both produce the same image (the near tier's contract), so a frame
/// may use the faster one: Auto takes Vulkan where the device is a GPU, and the CPU reference
/// where the only Vulkan device is a CPU implementation (lavapipe: the reference, natively
/// compiled on the same cores, is several times faster) or there is none at all.
enum class NearBackend { Auto, Vulkan, Reference };
/// The one table of near backend names, like kRenderModeNames.
inline constexpr std::array<std::pair<const char*, NearBackend>, 3> kNearBackendNames{{
    {"auto", NearBackend::Auto},
    {"vulkan", NearBackend::Vulkan},
    {"reference", NearBackend::Reference},
}};
/// Throws InputError(field "--near-backend") for a name not in kNearBackendNames.
NearBackend parseNearBackend(const std::string& name);
const char* toString(NearBackend b);

/// Who draws the far tier. Both produce the same image, bit for bit: the CPU blit into the near
/// image, or the Vulkan far pass (DESIGN.md §6) in the near tier's frame, into the same targets.
/// Auto takes Vulkan where the device is a GPU with shaderFloat64 and the CPU blit where the only
/// Vulkan device is a CPU implementation (lavapipe: the SIMD blit on the same cores is faster),
/// lacks shaderFloat64, or there is none.
enum class FarBackend { Auto, Vulkan, Cpu };
/// The one table of far backend names, like kRenderModeNames.
inline constexpr std::array<std::pair<const char*, FarBackend>, 3> kFarBackendNames{{
    {"auto", FarBackend::Auto},
    {"vulkan", FarBackend::Vulkan},
    {"cpu", FarBackend::Cpu},
}};
/// Throws InputError(field "--far-backend") for a name not in kFarBackendNames.
FarBackend parseFarBackend(const std::string& name);
const char* toString(FarBackend b);

/// The one table of far blit kernel names (impostor_cache/far_blit.hpp), like kRenderModeNames.
inline constexpr std::array<std::pair<const char*, FarBlitKernel>, 2> kFarBlitNames{{
    {"simd", FarBlitKernel::Simd},
    {"scalar", FarBlitKernel::Scalar},
}};
const char* toString(FarBlitKernel k);

/// The one table of near rate names (volumetric/near_rate.hpp), like kRenderModeNames.
inline constexpr std::array<std::pair<const char*, NearRate>, 3> kNearRateNames{{
    {"auto", NearRate::Auto},
    {"fragment", NearRate::Fragment},
    {"cell", NearRate::Cell},
}};
/// Throws InputError(field "--near-rate") for a name not in kNearRateNames.
NearRate parseNearRate(const std::string& name);
const char* toString(NearRate r);

struct FrameOptions {
    /// Of hybrid and far frames (reference frames use the CPU tracer, near frames Vulkan).
    NearBackend nearBackend = NearBackend::Auto;
    /// Per-pixel or cell-rate near sprites, on either backend (same image).
    NearRate nearRate = NearRate::Auto;
    /// Of hybrid and far frames: the CPU blit or the Vulkan far pass (same image).
    FarBackend farBackend = FarBackend::Auto;
    /// The far blit's kernel: SIMD (default) or the scalar reference (same image, for measuring).
    FarBlitOptions farBlit;
    VulkanDeviceOptions vulkan;                  ///< device options when Vulkan is used
    std::shared_ptr<VulkanMessageLog> vulkanLog; ///< validation messages (outlives the device)
    bool overlay = false;                        ///< also produce FrameResult::overlay (tier tint)
    /// FrameResult::pops: the change each switch causes, alone and seen (compose/pop_measure.hpp),
    /// measured after the frame's clock stops.
    bool measurePops = false;
    std::size_t cacheBudgetBytes = std::size_t(256) << 20; ///< far snapshot cache budget
    /// On-disk snapshot cache directory ("" = none): snapshots are read from it before baking and
    /// written to it after; cacheDirBytes limits its size (0 = no limit; LRU files go first).
    std::string cacheDir;
    std::uint64_t cacheDirBytes = 0;
    /// Near tier on Vulkan: the shader variant that counts voxel reads (FrameStats::voxelFetches,
    /// nearKernelFragments). Same image, slower: for measuring, never for timing.
    bool nearCountSteps = false;
    /// A near renderer to draw with instead of creating one: several FrameRenderers (bench
    /// configurations, views of one world) can share one Vulkan device. Null: created on first use.
    std::shared_ptr<NearRenderer> sharedNear;
    /// Metric error_budget: bakes that cost more than the near time the frame's far sprites save
    /// are given up (ErrorBudgetViews::keepAffordableBakes, DESIGN.md §5), by the costs measured
    /// on earlier frames, or by `bakeCosts` where set (a test must not depend on timing). false:
    /// only SelectorConfig::maxBakesPerFrame bounds the bakes.
    bool costAwareBakes = true;
    std::optional<BakeCosts> bakeCosts;
    /// Exact occlusion culling in the CPU tiers (the far blit and the CPU reference near tier;
    /// core/occlusion.hpp): the same image, bit for bit, with whole hidden sprites dropped before
    /// any bake or trace. Off by default (--cull turns it on): with earlyDepthTest on it costs
    /// more than it saves on every bench scene (DESIGN.md §6, Occlusion, with the figures).
    bool occlusionCull = false;
    /// The near tier's per-pixel early depth test on both backends (exact, and cheaper on every
    /// bench scene): the CPU reference skips pixels that already hold what beats the sprite
    /// (ReferenceOptions::earlyDepthTest), Vulkan draws front to back with the rasteriser's
    /// early depth test (NearOptions::earlyDepthTest). false (--no-cull, with occlusionCull):
    /// every covered pixel traced, in ascending id, the baseline culling is measured against.
    bool earlyDepthTest = true;
    /// Near sprites drawn by the CPU reference count their rows here (ReferenceOptions::progress;
    /// null: not counted), for a progress line polled by another thread. A Vulkan near tier is
    /// one submit per frame: it counts nothing.
    WorkProgress* nearProgress = nullptr;
    /// false: a frame whose near and far sprites are all drawn on Vulkan reads back the colour
    /// target alone (one plane of three), and FrameResult::image then has empty depth and id
    /// planes (the backdrop finds the pixels no sprite drew by their alpha). For output that
    /// reads neither (a PNG without --ids); the CPU tiers and the overlay need both.
    bool depthAndIds = true;
};

/// Where one frame's time went (wall-clock ms) and how much work each tier did. The step times
/// add up to totalMs except for small glue (image moves, bookkeeping):
/// totalMs ~ setupMs + selectMs + nearMs + farMs, nearMs ~ nearUploadMs + nearDrawMs +
/// nearReadbackMs on Vulkan, farMs = bakeMs + blitMs. Every field has a line in kFrameFigures
/// (compose/frame_figures.hpp), which names it in every output; the build checks that.
struct FrameStats {
    int entities = 0, culled = 0;
    int nearDrawn = 0, farDrawn = 0; ///< visible sprites drawn by each tier
    int fading = 0;                  ///< entities drawn by both tiers (cross-fade)
    int switchesToFar = 0, switchesToNear = 0, viewChanges = 0;
    int farBakes = 0; ///< snapshots baked during this frame
    /// Metric error_budget: bakes the planner asked for and gave up under the cost bound (their
    /// entities drawn near this frame; ErrorBudgetViews::keepAffordableBakes).
    int farBakesGivenUp = 0;
    /// Embree scenes the frame's bakes had to build first (a (model, animation frame, version)
    /// not in the cache's scene budget): each costs several bakes (DESIGN.md §4, Budget).
    int farScenesBuilt = 0;
    /// Edits (DESIGN.md §4): of the bakes, stale snapshots refreshed after an edit, how many of
    /// those only where the edit reaches, and the cells they re-traced; the voxel bytes the near
    /// tier copied to the GPU (whole frames when new, only dirty boxes after edits).
    int farRefreshes = 0, farIncrementalRefreshes = 0;
    std::uint64_t farCellsRetraced = 0, nearBytesUploaded = 0;
    std::uint64_t cacheBytes = 0; ///< snapshot bytes held after the frame
    /// bakeMs: the far tier making sure its snapshots exist (cache lookups + the bakes they start).
    double setupMs = 0.0, selectMs = 0.0, nearMs = 0.0, farMs = 0.0, bakeMs = 0.0, totalMs = 0.0;
    /// The Vulkan near tier's split of nearMs: voxel uploads to the atlas, record + submit + wait
    /// of the draw, copy of the three targets to host memory (0 with the reference backend).
    double nearUploadMs = 0.0, nearDrawMs = 0.0, nearReadbackMs = 0.0;
    /// Cell-rate near sprites (volumetric/near_rate.hpp): the Vulkan compute pass's GPU time
    /// (nearDrawMs is the rest of the frame's commands), cells traced once, pixels that traced
    /// their cell's rays and pixels that looked it up (Vulkan: the sprites' on-screen rectangle
    /// pixels), sprites drawn cell-rate and sprites that did not fit the cell budget.
    double nearComputeMs = 0.0;
    std::uint64_t nearCellsTraced = 0, nearPixelsTraced = 0, nearPixelsLookedUp = 0;
    int nearCellSprites = 0, nearCellOverBudget = 0;
    double blitMs = 0.0; ///< the far blit alone
    /// 1 when this frame's near sprites were drawn by the Vulkan near tier, 0 when by the CPU
    /// reference or when there were none (FrameRenderer::nearBackend says which Auto chose).
    int nearOnVulkan = 0;
    /// 1 when this frame's far sprites were drawn by the Vulkan far pass (blitMs is then its
    /// host preparation plus GPU time), 0 when by the CPU blit or when there were none.
    int farOnVulkan = 0;
    std::uint64_t nearPixelsTested = 0, farPixelsTested = 0, voxelFetches = 0;
    std::uint64_t farPixelsWritten = 0; ///< blit pixels a solid or outline cell won
    /// Near sprite pixels that took a solid or outline outcome (the CPU reference counts them;
    /// 0 on Vulkan).
    std::uint64_t nearPixelsWritten = 0;
    /// Visible sprites occlusion culling dropped whole, before any bake or trace (the CPU tiers;
    /// FrameOptions::occlusionCull), per tier.
    int nearOccluded = 0, farOccluded = 0;
    /// Near sprites Vulkan rasterised flat at their depth, under the early depth test
    /// (NearStats::earlyDepthSprites; FrameOptions::earlyDepthTest).
    std::uint64_t nearEarlyDepthSprites = 0;
    std::uint64_t nearKernelFragments = 0; ///< with nearCountSteps: fragments that ran the kernel
    std::uint64_t raysTraced = 0;          ///< by this frame's bakes
    /// The largest predicted silhouette displacement of a far-drawn entity (DESIGN.md §5,
    /// predictedBudgetUnits: virtual pixels, screen pixels where a cell is smaller).
    double farPredictedWorstVpx = 0.0;
};

struct FrameResult {
    Image image;
    std::optional<Image> overlay;     ///< with FrameOptions::overlay
    std::vector<SpriteSetup> sprites; ///< per entity id
    std::vector<EntityPlan> plan;     ///< per entity id
    std::vector<PopEvent> pops;       ///< with FrameOptions::measurePops
    FrameStats stats;
};

class FrameRenderer {
  public:
    explicit FrameRenderer(Scene& scene, FrameOptions options = {});
    ~FrameRenderer();
    FrameRenderer(const FrameRenderer&) = delete;
    FrameRenderer& operator=(const FrameRenderer&) = delete;

    /// Applies the scene's scripted edits due up to path frame `frame` (each once).
    void applyEditsThrough(int frame);
    /// One frame at time t; `frame` only labels pop events. Consecutive calls are consecutive
    /// frames for the selector (hysteresis, cross-fades).
    FrameResult render(double time, RenderMode mode, int frame = 0);

    /// Draws `sprites` as `plan` says, with no selector involved: near sprites (and the near
    /// half of fades) by options().nearBackend, then far ones through the cache, composed by
    /// min-z. `onlyTier` draws just that tier's share (for tests and debugging).
    Image draw(const CameraFrame& camera, const std::vector<SpriteSetup>& sprites,
               const std::vector<EntityPlan>& plan, FrameStats* stats = nullptr,
               std::optional<Tier> onlyTier = std::nullopt);

    SnapshotCache& snapshotCache() { return *cache_; }
    TierSelector& selector() { return planner_.selector(); }
    const FrameOptions& options() const { return options_; }
    /// Changes apply from the next frame (the cache budget only through snapshotCache().setBudget).
    FrameOptions& options() { return options_; }
    /// The Vulkan device of the near tier ("" until a frame needed it).
    std::string nearDeviceName() const;
    /// Who draws near sprites in hybrid and far frames: options().nearBackend, or what Auto
    /// chose on this machine (decided once, probing the Vulkan loader, before the first hybrid
    /// frame's clock starts, by the first other frame that draws a near sprite, or by this
    /// call).
    NearBackend nearBackend();
    /// Auto's choice and its reason in one line ("" when the backend was given, not chosen).
    const std::string& nearBackendChoice();
    /// Who draws far sprites in hybrid and far frames: options().farBackend, or what Auto chose
    /// (decided once, like nearBackend()).
    FarBackend farBackend();
    /// Auto's choice and its reason in one line ("" when the backend was given, not chosen).
    const std::string& farBackendChoice();

  private:
    /// Step 2: the planner's plan for this frame (lod/frame_planner.hpp), its figures into `st`.
    std::vector<EntityPlan> planEntities(const std::vector<SpriteSetup>& sprites, RenderMode mode,
                                         FrameStats& st);
    /// The near tier's per-frame cost whatever it draws (ms): measured once, drawing nothing.
    /// The figure the planner's cost model asks for (CostModel::observe); compose only measures.
    double nearFixedMs(const CameraFrame& camera, NearBackend nearBackend);
    /// draw() with the near tier drawn by `nearBackend`.
    Image drawWith(NearBackend nearBackend, const CameraFrame& camera,
                   const std::vector<SpriteSetup>& sprites, const std::vector<EntityPlan>& plan,
                   FrameStats& stats, std::optional<Tier> onlyTier = std::nullopt);
    /// `b`, with Auto resolved (nearBackend()).
    NearBackend resolved(NearBackend b) { return b == NearBackend::Auto ? nearBackend() : b; }
    /// The near sprites by `nearBackend`; with `far`, Vulkan draws them (all near sprites on
    /// Vulkan, or none) and the far batch in one frame.
    Image drawNear(NearBackend nearBackend, const CameraFrame& camera,
                   const std::vector<const SpriteSetup*>& sprites, FrameStats& stats,
                   const FarBatch* far = nullptr, bool colourOnly = false);
    /// Whether a frame drawn wholly on Vulkan may read back its colour alone.
    bool colourOnly() const {
        return !options_.depthAndIds && !options_.overlay && !options_.measurePops;
    }
    /// The Vulkan probe both Auto choices read (the shared device's answer where there is one).
    const VulkanProbe& vulkanProbe();
    NearRenderer& nearRenderer();
    void drawFar(const std::vector<FarRequest>& requests, Image& image, FrameStats& stats);
    Image tierOverlay(const Image& image, const std::vector<EntityPlan>& plan) const;

    Scene& scene_;
    FrameOptions options_;
    FramePlanner planner_; ///< the LOD policy: selector, error budget views, cost model
    struct NearFixed {
        double ms = -1.0; ///< < 0: not measured yet
        bool vulkan = false;
        int width = 0, height = 0;
    } nearFixed_; ///< nearFixedMs(), for the backend and image size it was measured with
    std::optional<NearBackend> autoChoice_; ///< what NearBackend::Auto resolved to
    std::string autoReason_;
    std::optional<FarBackend> farAutoChoice_; ///< what FarBackend::Auto resolved to
    std::string farAutoReason_;
    std::optional<VulkanProbe> probe_;
    std::unique_ptr<SnapshotCache> cache_;
    std::shared_ptr<NearRenderer>
        near_; ///< options.sharedNear, or created by the first frame that draws near on Vulkan
    std::vector<EntityPlan> previousPlan_;
    int editsApplied_ = 0; ///< scene.edits are applied in order of atFrame
};

/// Composes `far` into `near` by the shared depth/id rule (core/sprite.hpp winsDepthTest).
/// The frame itself blits far sprites straight into the near image with the same rule; this is
/// the same operation for two finished images.
void composeMinZ(Image& near, const Image& far);

} // namespace voxtier
