#pragma once
// The frame recipe of CONTRACT.md §6: select tiers -> draw near sprites (Vulkan) -> ensure the
// snapshots far sprites need (lazy, parallel) -> blit far sprites -> compose by min-z (with
// FarBackend::Vulkan, one Vulkan frame draws the near sprites and then the far ones). compose/
// draws and composes; the selection, its views and the bakes it can afford are lod/'s
// (lod/frame_planner.hpp). A FrameRenderer keeps what persists between frames of one scene: the
// planner (the selector's per-entity state, the budget's views, the measured costs), the
// snapshot cache and the Vulkan device with its voxel atlas.
#include "compose/pop_measure.hpp"
#include "core/image.hpp"
#include "core/near_rate.hpp"
#include "core/scene.hpp"
#include "core/shared_vector.hpp"
#include "core/sprite.hpp"
#include "core/sprite_store.hpp"
#include "core/view_set.hpp"
#include "core/work_progress.hpp"
#include "device/vulkan_options.hpp"
#include "impostor_cache/far_batch.hpp"
#include "impostor_cache/far_blit.hpp"
#include "impostor_cache/far_stats.hpp"
#include "lod/frame_planner.hpp"
#include "lod/selector.hpp"
#include "volumetric/near_stats.hpp"

#include <array>
#include <cstddef>
#include <cstdint>
#include <functional>
#include <initializer_list>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <utility>
#include <vector>

namespace voxtier {

class NearRenderer;
class FarPass;
struct VulkanFrameInFlight;
class SnapshotCache;
struct FarRequest;
struct FarBatch;
struct FarDraws;

enum class RenderMode {
    Reference, ///< every entity through the CPU reference tracer (the executable spec)
    Near,      ///< every entity through the Vulkan near tier (volumetric/near_renderer.hpp)
    Far,       ///< every entity through the far tier's snapshot cache (CONTRACT.md §4)
    Hybrid,    ///< the selector decides per entity (CONTRACT.md §5): the product's main job
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
/// image, or the Vulkan far pass (CONTRACT.md §6) in the near tier's frame, into the same targets.
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

/// The one table of near rate names (core/near_rate.hpp), like kRenderModeNames.
inline constexpr std::array<std::pair<const char*, NearRate>, 3> kNearRateNames{{
    {"auto", NearRate::Auto},
    {"fragment", NearRate::Fragment},
    {"cell", NearRate::Cell},
}};
/// Throws InputError(field "--near-rate") for a name not in kNearRateNames.
NearRate parseNearRate(const std::string& name);
const char* toString(NearRate r);

/// The one table of names of how Vulkan traces per-pixel near sprites (NearPixels).
inline constexpr std::array<std::pair<const char*, NearPixels>, 3> kNearPixelsNames{{
    {"auto", NearPixels::Auto},
    {"compute", NearPixels::Compute},
    {"raster", NearPixels::Raster},
}};
const char* toString(NearPixels p);

/// The one table of names of where the Vulkan near tier lays its sprite records (NearRecords).
inline constexpr std::array<std::pair<const char*, NearRecords>, 2> kNearRecordsNames{{
    {"drawn", NearRecords::Drawn},
    {"given", NearRecords::Given},
}};
const char* toString(NearRecords r);

/// The one table of names of the ways the Vulkan far pass is cut (FarTiles).
inline constexpr std::array<std::pair<const char*, FarTiles>, 4> kFarTilesNames{{
    {"auto", FarTiles::Auto},
    {"coarse", FarTiles::Coarse},
    {"fine", FarTiles::Fine},
    {"sprites", FarTiles::Sprites},
}};

struct FrameOptions {
    /// Of hybrid and far frames (reference frames use the CPU tracer, near frames Vulkan).
    NearBackend nearBackend = NearBackend::Auto;
    /// Per-pixel or cell-rate near sprites, on either backend (same image).
    NearRate nearRate = NearRate::Auto;
    /// The Vulkan near tier's per-pixel sprites drawn or traced in compute (same image).
    NearPixels nearPixels = NearPixels::Auto;
    /// Where the Vulkan near tier lays its sprite records (same image).
    NearRecords nearRecords = NearRecords::Drawn;
    /// Of hybrid and far frames: the CPU blit or the Vulkan far pass (same image).
    FarBackend farBackend = FarBackend::Auto;
    /// The Vulkan far pass's tiles: 32 or 8 pixels a side (same image;
    /// impostor_cache/far_pass.hpp).
    FarTiles farTiles = FarTiles::Auto;
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
    /// Near tier on Vulkan: the shader variant that counts voxel reads (NearStats::voxelFetches,
    /// kernelFragments). Same image, slower: for measuring, never for timing.
    bool nearCountSteps = false;
    /// A near renderer to draw with instead of creating one: several FrameRenderers (bench
    /// configurations, views of one world) can share one Vulkan device. Null: created on first use.
    std::shared_ptr<NearRenderer> sharedNear;
    /// Metric error_budget: bakes that cost more than the near time the frame's far sprites save
    /// are given up (ErrorBudgetViews::keepAffordableBakes, CONTRACT.md §5), by the costs measured
    /// on earlier frames, or by `bakeCosts` where set (a test must not depend on timing). false:
    /// only SelectorConfig::maxBakesPerFrame bounds the bakes.
    bool costAwareBakes = true;
    std::optional<BakeCosts> bakeCosts;
    /// Metric error_budget: the planner keeps the snapshot cache's answers from frame to frame
    /// and asks again only about the snapshots the cache baked, loaded or dropped since
    /// (PlanSettings::inMemoryChangesSince). false: every frame asks afresh (the same plans; for
    /// comparing the two).
    bool keepCacheAnswers = true;
    /// Exact occlusion culling in the CPU tiers (the far blit and the CPU reference near tier;
    /// core/occlusion.hpp): the same image, bit for bit, with whole hidden sprites dropped before
    /// any bake or trace. Off by default (--cull turns it on): with earlyDepthTest on it costs
    /// more than it saves on every bench scene (docs/decisions/occlusion-and-early-depth.md).
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
    /// false: a frame drawn wholly on Vulkan is drawn and timed but not read back
    /// (FrameResult::image is empty): the device frame alone, for measuring it.
    bool readBack = true;
    /// The Vulkan near tier's empty-space skipping (NearOptions::skipEmpty; the CPU reference
    /// always skips where a sprite's model frame qualifies). The same image either way.
    bool nearSkipEmpty = false;
};

/// A frame drawn on Vulkan: the host's share of it and the device's named passes (ms; 0 where
/// the device has no timestamps or the frame had no such pass).
struct VulkanFrameTimes {
    /// On the host: preparing and recording the passes (uploads written), blocked on the fence,
    /// and unpacking what was read back.
    double hostRecordMs = 0.0, hostWaitMs = 0.0, hostReadbackMs = 0.0;
    /// On the device: the whole frame, its uploads, the cell-rate cells, splat and resolve, the
    /// per-pixel sprites (drawn, or traced in compute), the far pass, and the copies of the
    /// planes (targets into the planes, planes into host memory).
    double gpuFrameMs = 0.0, gpuUploadMs = 0.0, gpuCellsMs = 0.0, gpuSplatMs = 0.0, gpuDrawMs = 0.0,
           gpuResolveMs = 0.0, gpuFarMs = 0.0, gpuCopyMs = 0.0;
    /// The far pass's share of the frame: its recording, its upload and its device time.
    double farPassMs = 0.0;
    /// Of farPassMs, the snapshots' uploads: writing and recording them on the host
    /// (FarPassStats::snapshotUploadMs) and copying them on the device ("far_snapshots").
    double farSnapshotsMs = 0.0;
    /// Of hostRecordMs, the far pass's recording (its order, palettes, tiles and instances).
    double hostRecordFarMs = 0.0;
};

/// What a frame did. The frame's own figures (its steps on the host, what each tier drew; the
/// steps add up to totalMs but for small glue: totalMs ~ hostSetupMs + hostSelectMs + nearMs +
/// farMs), then each backend's figures as that backend reported them, zero where it drew nothing
/// this frame. The output columns (compose/frame_figures.hpp) read them; several combine the
/// backends (a frame's near sprites are drawn by one near backend, so "near_fragments" is the
/// reference's pixels tested or the Vulkan draw's fragment invocations).
struct FrameStats {
    int entities = 0, culled = 0;
    int nearDrawn = 0, farDrawn = 0; ///< visible sprites drawn by each tier
    /// The frame's steps on the host (wall-clock ms): set-up (step 1), selection (step 2), the
    /// near tier, the far tier (its cache lookups and bakes, far.ensureMs, then the blit or the
    /// far pass), and the whole frame.
    double hostSetupMs = 0.0, hostSelectMs = 0.0, nearMs = 0.0, farMs = 0.0, totalMs = 0.0;
    std::uint64_t cacheBytes = 0; ///< snapshot bytes held after the frame
    /// 1 when this frame's near sprites were drawn by the Vulkan near tier, 0 when by the CPU
    /// reference or when there were none (FrameRenderer::nearBackend says which Auto chose).
    int nearOnVulkan = 0;
    /// 1 when this frame's far sprites were drawn by the Vulkan far pass, 0 when by the CPU blit
    /// or when none.
    int farOnVulkan = 0;

    PlanStats plan;           ///< the selection (lod/frame_planner.hpp): switches, fades, views
    ReferenceStats reference; ///< the near tier on the CPU (volumetric/near_stats.hpp)
    NearStats vulkanNear;     ///< the near tier on Vulkan
    FarFrameStats far;        ///< the far tier's cache work; with the CPU blit, far.blit
    FarPassStats vulkanFar;   ///< the far tier on Vulkan (impostor_cache/far_stats.hpp)
    VulkanFrameTimes vulkan;  ///< a frame drawn on Vulkan
};

struct FrameResult {
    Image image;
    std::optional<Image> overlay; ///< with FrameOptions::overlay
    /// Per entity id: shares of the renderer's own arrays (core/shared_vector.hpp), so a frame
    /// hands them out without copying; they stay this frame's when later frames are drawn.
    SharedVector<SpriteSetup> sprites;
    SharedVector<EntityPlan> plan;
    std::vector<PopEvent> pops; ///< with FrameOptions::measurePops
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
    /// frames for the selector (hysteresis, cross-fades). render() is finish(submit(...)).
    FrameResult render(double time, RenderMode mode, int frame = 0);

    /// A frame begun by submit() and not yet finished.
    struct Pending;
    struct PendingDeleter {
        void operator()(Pending* p) const;
    };
    using PendingFrame = std::unique_ptr<Pending, PendingDeleter>;
    /// One frame in two halves, so that the host prepares frame k+1 while the device draws
    /// frame k (a path render keeps two frames in flight): submit() runs set-up, selection and
    /// the bakes and, for a frame drawn wholly on Vulkan, records and submits it; finish() waits
    /// for it, reads it back and completes the frame (backdrop, overlay, pops, cost model). A
    /// frame with a CPU tier is drawn whole by submit(). Finish frames in the order submitted,
    /// at most two in flight.
    /// `selected`, if given, runs once the frame is set up and selected, before it is drawn or
    /// recorded: a caller's work that should share the cores with the drawing rather than with
    /// the set-up and selection (the render command's writing of the frame before's files).
    PendingFrame submit(double time, RenderMode mode, int frame = 0,
                        const std::function<void()>& selected = {});
    FrameResult finish(PendingFrame frame);

    /// Draws `sprites` as `plan` says, with no selector involved: near sprites (and the near
    /// half of fades) by options().nearBackend, then far ones through the cache, composed by
    /// min-z. `onlyTier` draws just that tier's share (for tests and debugging).
    Image draw(const CameraFrame& camera, std::span<const SpriteSetup> sprites,
               std::span<const EntityPlan> plan, FrameStats* stats = nullptr,
               std::optional<Tier> onlyTier = std::nullopt);
    Image draw(const CameraFrame& camera, std::span<const SpriteSetup> sprites,
               std::initializer_list<EntityPlan> plan, FrameStats* stats = nullptr,
               std::optional<Tier> onlyTier = std::nullopt) {
        return draw(camera, sprites, std::span<const EntityPlan>(plan.begin(), plan.size()), stats,
                    onlyTier);
    }

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
    SharedVector<EntityPlan> planEntities(RenderMode mode, FrameStats& st);
    /// The near tier's per-frame cost whatever it draws (ms): measured once, drawing nothing.
    /// The figure the planner's cost model asks for (CostModel::observe); compose only measures.
    double nearFixedMs(const CameraFrame& camera, NearBackend nearBackend);
    /// draw() with the near tier drawn by `nearBackend`.
    /// `visible`: the visible sprites' ids, ascending (empty: found from `sprites`). With
    /// `pending`, a frame drawn wholly on Vulkan is only submitted (into *pending), and the image
    /// returned is empty until finish().
    /// `history`: where `sprites` are the store's this update (what changed when, for the near
    /// tier's records).
    Image drawWith(NearBackend nearBackend, const CameraFrame& camera,
                   std::span<const SpriteSetup> sprites, std::span<const EntityPlan> plan,
                   FrameStats& stats, std::optional<Tier> onlyTier = std::nullopt,
                   std::span<const std::uint32_t> visible = {}, Pending* pending = nullptr,
                   const SpriteHistory* history = nullptr);
    /// `b`, with Auto resolved (nearBackend()).
    NearBackend resolved(NearBackend b) { return b == NearBackend::Auto ? nearBackend() : b; }
    /// One Vulkan frame (compose/vulkan_frame.hpp): `sprites` by the near passes, then `far`
    /// (may be null) by the far pass; colour alone read back when `colourOnly`.
    /// `farAfterNear` in place of `far`: the far sprites found while the device draws the near
    /// ones (VulkanFrameRequest::farAfterNear).
    Image drawOnVulkan(const CameraFrame& camera, const std::vector<const SpriteSetup*>& sprites,
                       const FarBatch* far, bool colourOnly, FrameStats& stats,
                       Pending* pending = nullptr, const SpriteHistory* history = nullptr,
                       const std::function<const FarBatch*()>& farAfterNear = {});
    /// drawOnVulkan's first half: the frame recorded and submitted, not waited for. `readBack`:
    /// whether it is read back (a CPU tier composes on it, or FrameOptions::readBack).
    VulkanFrameInFlight submitOnVulkan(const CameraFrame& camera,
                                       const std::vector<const SpriteSetup*>& sprites,
                                       const FarBatch* far, bool colourOnly, bool readBack,
                                       FrameStats& stats, const SpriteHistory* history,
                                       const std::function<const FarBatch*()>& farAfterNear = {});
    /// finish() of a Vulkan frame: read back, its figures into `stats`.
    Image finishOnVulkan(VulkanFrameInFlight&& frame, bool hasFar, FrameStats& stats);
    /// The near sprites by the CPU reference.
    Image drawNearCpu(const CameraFrame& camera, const std::vector<const SpriteSetup*>& sprites,
                      FrameStats& stats);
    /// Whether a frame drawn wholly on Vulkan may read back its colour alone.
    bool colourOnly() const {
        return !options_.depthAndIds && !options_.overlay && !options_.measurePops;
    }
    /// The Vulkan probe both Auto choices read (the shared device's answer where there is one).
    const VulkanProbe& vulkanProbe();
    NearRenderer& nearRenderer();
    FarPass& farPass();
    void drawFar(const std::vector<FarRequest>& requests, Image& image, FrameStats& stats);
    /// drawFar's blit of snapshots fetched ahead (fetchFarSnapshots, while the device drew).
    void blitFar(const FarDraws& draws, Image& image, FrameStats& stats);
    Image tierOverlay(const Image& image, std::span<const EntityPlan> plan) const;

    Scene& scene_;
    FrameOptions options_;
    SpriteStore sprites_;  ///< the entities' sprites, kept between frames (set-up, step 1)
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
    std::unique_ptr<FarPass> farPass_; ///< on near_'s frames, created by the first far pass
    /// Which sprites each tier draws this frame (drawWith), its arrays kept between frames.
    struct TierShares;
    std::unique_ptr<TierShares> shares_;
    SharedVector<EntityPlan> previousPlan_; ///< kept with FrameOptions::measurePops only
    int editsApplied_ = 0;                  ///< scene.edits are applied in order of atFrame
    /// The models' (uid, version) the planner's kept cache answers are about, and the epoch
    /// that names them (PlanSettings::inMemoryEpoch): a new epoch when any of them changes.
    std::vector<std::pair<std::uint64_t, std::uint64_t>> answeredModels_;
    std::uint64_t answersEpoch_ = 0;
};

/// Composes `far` into `near` by the shared depth/id rule (core/sprite.hpp winsDepthTest).
/// The frame itself blits far sprites straight into the near image with the same rule; this is
/// the same operation for two finished images.
void composeMinZ(Image& near, const Image& far);

} // namespace voxtier
