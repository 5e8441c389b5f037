// The frame recipe (CONTRACT.md §6). FrameRenderer::render reads top to bottom as the recipe;
// everything else in this file is a step it calls.
#include "compose/frame.hpp"

#include "compose/backdrop.hpp"
#include "compose/tier_legend.hpp"
#include "compose/vulkan_frame.hpp"
#include "core/error.hpp"
#include "core/stopwatch.hpp"
#include "core/view_set.hpp"
#include "impostor_cache/far_batch.hpp"
#include "impostor_cache/far_frame.hpp"
#include "impostor_cache/far_pass.hpp"
#include "impostor_cache/snapshot_cache.hpp"
#include "volumetric/near_renderer.hpp"
#include "volumetric/reference_renderer.hpp"

#include <tbb/parallel_for.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>

namespace voxtier {

namespace {

using Clock = std::chrono::steady_clock;

/// A copy of a sprite that draws only its share of a cross-fade: `keepBelow` keeps the pixels
/// whose dither threshold is below the fade share (the new tier), the others keep the rest.
SpriteSetup fadedCopy(const SpriteSetup& s, float share, bool keepBelow) {
    SpriteSetup c = s;
    c.gpu.fade = share;
    c.gpu.fadeSide = keepBelow ? 1.0f : -1.0f;
    return c;
}

/// Who draws near sprites: reference mode is the CPU tracer by definition, near mode is Vulkan,
/// the others use the configured backend (Auto resolved by FrameRenderer::nearBackend).
NearBackend nearBackendFor(RenderMode mode, NearBackend configured) {
    return mode == RenderMode::Reference ? NearBackend::Reference
           : mode == RenderMode::Near    ? NearBackend::Vulkan
                                         : configured;
}

/// The value `name` stands for in a name table, else InputError naming `field` and the names.
template <class E, std::size_t N>
E fromName(const std::array<std::pair<const char*, E>, N>& names, const std::string& name,
           const char* field, const char* what) {
    std::string allowed;
    for (const auto& [n, value] : names) {
        if (name == n) return value;
        allowed += (allowed.empty() ? "" : ", ") + std::string(n);
    }
    throw InputError(
        "", field, "unknown " + std::string(what) + " '" + name + "' (expected: " + allowed + ")");
}

template <class E, std::size_t N>
const char* nameOf(const std::array<std::pair<const char*, E>, N>& names, E value) {
    for (const auto& [n, v] : names)
        if (v == value) return n;
    return "?";
}

} // namespace

RenderMode parseRenderMode(const std::string& name) {
    return fromName(kRenderModeNames, name, "--mode", "render mode");
}

const char* toString(RenderMode m) {
    return nameOf(kRenderModeNames, m);
}

NearBackend parseNearBackend(const std::string& name) {
    return fromName(kNearBackendNames, name, "--near-backend", "near backend");
}

const char* toString(NearBackend b) {
    return nameOf(kNearBackendNames, b);
}

FarBackend parseFarBackend(const std::string& name) {
    return fromName(kFarBackendNames, name, "--far-backend", "far backend");
}

const char* toString(FarBackend b) {
    return nameOf(kFarBackendNames, b);
}

const char* toString(FarBlitKernel k) {
    return nameOf(kFarBlitNames, k);
}

NearRate parseNearRate(const std::string& name) {
    return fromName(kNearRateNames, name, "--near-rate", "near rate");
}

const char* toString(NearRate r) {
    return nameOf(kNearRateNames, r);
}

const char* toString(NearPixels p) {
    return nameOf(kNearPixelsNames, p);
}

const char* toString(NearRecords r) {
    return nameOf(kNearRecordsNames, r);
}

namespace {
SnapshotCacheConfig cacheConfig(const FrameOptions& o, const SelectorConfig& selector) {
    SnapshotCacheConfig c;
    c.bake.snapshotScale = selector.snapshotScale;
    c.budgetBytes = o.cacheBudgetBytes;
    if (!o.cacheDir.empty())
        c.store = std::make_shared<SnapshotStore>(
            SnapshotStoreOptions{.dir = o.cacheDir, .limitBytes = o.cacheDirBytes});
    return c;
}

/// The Vulkan frame's times, host and device, by the passes' names (the tiers name them: the
/// near passes in volumetric/near_passes.cpp, the far pass in impostor_cache/far_pass.cpp).
VulkanFrameTimes timesOf(const GpuFrameReport& g) {
    VulkanFrameTimes t;
    t.hostRecordMs = g.recordMs;
    t.hostWaitMs = g.host.waitMs;
    t.hostReadbackMs = g.host.readbackMs;
    const auto sum = [&](std::initializer_list<const char*> names) {
        double ms = 0.0;
        for (const char* n : names) ms += g.ms(n).value_or(0.0);
        return ms;
    };
    t.gpuFrameMs = sum({"frame", "frame_rest"}); // a frame in two parts: the gap is not its
    t.gpuUploadMs = sum({"near_upload", "far_upload"});
    t.gpuCellsMs = sum({"near_cells"});
    t.gpuSplatMs = sum({"near_splat"});
    t.gpuDrawMs = sum({"near_draw", "near_trace"});
    t.gpuResolveMs = sum({"near_resolve"});
    t.gpuFarMs = sum({"far_blit"});
    t.gpuCopyMs = sum({"copy_planes", "readback_copy"});
    return t;
}

} // namespace

/// Which sprites each tier draws. A cross-fading sprite is drawn by both tiers, each with a copy
/// that keeps the complementary half of the dither pattern (the new tier takes the pixels below
/// the share). The lists hold indices into the frame's sprites followed by `faded`, in the
/// order of the visible ids. Kept by the renderer and filled on every core: at 100,000 tanks
/// one core built the lists by appending, growing each array afresh every frame (a megabyte
/// and more a frame, before the near tier's recording began).
struct FrameRenderer::TierShares {
    std::vector<SpriteSetup> faded;
    std::vector<std::size_t> near;
    std::vector<std::pair<std::size_t, std::optional<ViewId>>> far; ///< sprite, view override
    /// The sprites `near` lists, and what the far tier is asked for those `far` lists.
    std::vector<const SpriteSetup*> nearSprites;
    std::vector<FarRequest> farRequests;
    /// The far pass's batch of `farRequests` (drawWith, far pass on Vulkan), and its scratch:
    /// arrays kept; the batch's snapshots are let go once the frame is recorded.
    FarBatch farBatch;
    FarBatchScratch farScratch;

    /// `visible`: the visible sprites' ids, ascending.
    void fill(std::span<const SpriteSetup> sprites, std::span<const EntityPlan> plan,
              std::span<const std::uint32_t> visible, std::optional<Tier> onlyTier) {
        sprites_ = sprites;
        // Whether an entity is drawn near, far, and far in the view it fades from.
        struct Draws {
            bool near, far, fromView;
        };
        const auto drawsOf = [&](const EntityPlan& p) {
            return Draws{p.drawsNear() && onlyTier != Tier::Far,
                         p.drawsFar() && onlyTier != Tier::Near,
                         p.fadeFromView && p.fade > 0.0f && onlyTier != Tier::Near};
        };
        // What each visible entity adds to each list (a fading one's shares are copies): counted
        // per chunk of them in parallel, then each chunk fills its lists from its offsets, in the
        // order of `visible`.
        const auto countsOf = [&](const EntityPlan& p) {
            const Draws d = drawsOf(p);
            const std::size_t shares = std::size_t(d.near) + d.far + d.fromView;
            return Counts{d.near, std::size_t(d.far) + d.fromView, p.fade > 0.0f ? shares : 0};
        };
        constexpr std::size_t kChunk = 4096;
        const std::size_t chunks = (visible.size() + kChunk - 1) / kChunk;
        at_.assign(chunks + 1, Counts{});
        tbb::parallel_for(std::size_t(0), chunks, [&](std::size_t c) {
            Counts& sum = at_[c + 1];
            for (std::size_t j = c * kChunk; j != std::min(visible.size(), (c + 1) * kChunk); ++j) {
                const Counts k = countsOf(plan[visible[j]]);
                sum.near += k.near, sum.far += k.far, sum.faded += k.faded;
            }
        });
        for (std::size_t c = 0; c < chunks; ++c) {
            at_[c + 1].near += at_[c].near;
            at_[c + 1].far += at_[c].far;
            at_[c + 1].faded += at_[c].faded;
        }
        near.resize(at_[chunks].near);
        far.resize(at_[chunks].far);
        faded.resize(at_[chunks].faded);
        tbb::parallel_for(std::size_t(0), chunks, [&](std::size_t c) {
            Counts next = at_[c];
            // The sprite a tier draws: the entity's own, or a copy with its share of the fade.
            const auto share = [&](std::uint32_t i, const EntityPlan& p, bool keepBelow) {
                if (p.fade <= 0.0f) return std::size_t(i);
                faded[next.faded] = fadedCopy(sprites_[i], p.fade, keepBelow);
                return sprites_.size() + next.faded++;
            };
            for (std::size_t j = c * kChunk; j != std::min(visible.size(), (c + 1) * kChunk); ++j) {
                const std::uint32_t i = visible[j];
                const EntityPlan& p = plan[i];
                const Draws d = drawsOf(p);
                if (d.near) near[next.near++] = share(i, p, /*keepBelow=*/p.tier == Tier::Near);
                if (d.far)
                    far[next.far++] = {share(i, p, /*keepBelow=*/p.tier == Tier::Far), p.view};
                if (d.fromView)
                    far[next.far++] = {share(i, p, /*keepBelow=*/false), p.fadeFromView};
            }
        });
        nearSprites.resize(near.size());
        tbb::parallel_for(tbb::blocked_range<std::size_t>(0, near.size(), 4096),
                          [&](const auto& r) {
                              for (std::size_t k = r.begin(); k != r.end(); ++k)
                                  nearSprites[k] = &at(near[k]);
                          });
        farRequests.resize(far.size());
        tbb::parallel_for(tbb::blocked_range<std::size_t>(0, far.size(), 4096), [&](const auto& r) {
            for (std::size_t k = r.begin(); k != r.end(); ++k)
                farRequests[k] = {&at(far[k].first), far[k].second};
        });
    }

  private:
    std::span<const SpriteSetup> sprites_;
    struct Counts {
        std::size_t near = 0, far = 0, faded = 0;
    };
    /// Per chunk of the visible ids, where its entries of each list begin (the last: the sizes).
    std::vector<Counts> at_;
    const SpriteSetup& at(std::size_t k) const {
        return k < sprites_.size() ? sprites_[k] : faded[k - sprites_.size()];
    }
};

FrameRenderer::FrameRenderer(Scene& scene, FrameOptions options)
    : scene_(scene), options_(options), planner_(scene.selector),
      cache_(std::make_unique<SnapshotCache>(cacheConfig(options, scene.selector))) {
    std::stable_sort(
        scene_.edits.begin(), scene_.edits.end(),
        [](const ScriptedEdit& a, const ScriptedEdit& b) { return a.atFrame < b.atFrame; });
}

FrameRenderer::~FrameRenderer() = default;

std::string FrameRenderer::nearDeviceName() const {
    return near_ ? near_->deviceName() : std::string();
}

const VulkanProbe& FrameRenderer::vulkanProbe() {
    if (!probe_) {
        // A shared device (the bench's) is asked what it is; otherwise the loader is probed.
        VulkanProbe probe;
        if (options_.sharedNear) {
            probe.found = true;
            probe.cpu = options_.sharedNear->deviceIsCpu();
            probe.name = options_.sharedNear->deviceName();
            probe.float64 = FarPass::supported(options_.sharedNear->device());
        } else {
            probe = probeVulkanDevice();
        }
        probe_ = probe;
    }
    return *probe_;
}

FarPass& FrameRenderer::farPass() {
    // Created on first use, on the near tier's device and frames: one frame draws both tiers.
    if (!farPass_) farPass_ = std::make_unique<FarPass>(nearRenderer().frames(), options_.farTiles);
    return *farPass_;
}

NearRenderer& FrameRenderer::nearRenderer() {
    // Created on first use: reference- and CPU-only runs never touch Vulkan.
    if (!near_)
        near_ = options_.sharedNear
                    ? options_.sharedNear
                    : std::make_shared<NearRenderer>(options_.vulkan, options_.vulkanLog);
    return *near_;
}

FarBackend FrameRenderer::farBackend() {
    if (options_.farBackend != FarBackend::Auto) return options_.farBackend;
    if (!farAutoChoice_) {
        const VulkanProbe& probe = vulkanProbe();
        farAutoChoice_ =
            probe.found && !probe.cpu && probe.float64 ? FarBackend::Vulkan : FarBackend::Cpu;
        farAutoReason_ =
            !probe.found ? "far tier: CPU blit (--far-backend auto: " + probe.whyNone + ")"
            : probe.cpu
                ? "far tier: CPU blit (--far-backend auto: the only Vulkan device, " + probe.name +
                      ", runs on the CPU, where the SIMD blit is faster; --far-backend "
                      "vulkan uses it)"
            : !probe.float64 ? "far tier: CPU blit (--far-backend auto: " + probe.name +
                                   " lacks shaderFloat64, which the far pass needs)"
                             : "far tier: Vulkan on " + probe.name + " (--far-backend auto)";
    }
    return *farAutoChoice_;
}

const std::string& FrameRenderer::farBackendChoice() {
    static const std::string none;
    if (options_.farBackend != FarBackend::Auto) return none;
    farBackend();
    return farAutoReason_;
}

NearBackend FrameRenderer::nearBackend() {
    if (options_.nearBackend != NearBackend::Auto) return options_.nearBackend;
    if (!autoChoice_) {
        const VulkanProbe& probe = vulkanProbe();
        autoChoice_ = probe.found && !probe.cpu ? NearBackend::Vulkan : NearBackend::Reference;
        autoReason_ =
            !probe.found ? "near tier: CPU reference (--near-backend auto: " + probe.whyNone + ")"
            : probe.cpu
                ? "near tier: CPU reference (--near-backend auto: the only Vulkan device, " +
                      probe.name +
                      ", runs on the CPU, where the reference is faster; --near-backend "
                      "vulkan uses it)"
                : "near tier: Vulkan on " + probe.name + " (--near-backend auto)";
    }
    return *autoChoice_;
}

const std::string& FrameRenderer::nearBackendChoice() {
    static const std::string none;
    if (options_.nearBackend != NearBackend::Auto) return none;
    nearBackend();
    return autoReason_;
}

void FrameRenderer::applyEditsThrough(int frame) {
    while (editsApplied_ < int(scene_.edits.size()) &&
           scene_.edits[std::size_t(editsApplied_)].atFrame <= frame) {
        const ScriptedEdit& e = scene_.edits[std::size_t(editsApplied_++)];
        VoxelModel& m = *scene_.models.at(std::size_t(e.model));
        switch (e.op) {
        case ScriptedEdit::Op::Set:
            m.setVoxel(e.modelFrame, e.box.min, e.index);
            break;
        case ScriptedEdit::Op::Fill:
            m.fillBox(e.modelFrame, e.box, e.index);
            break;
        case ScriptedEdit::Op::Clear:
            m.clearBox(e.modelFrame, e.box);
            break;
        }
    }
}

/// What a submitted frame still needs to finish.
struct FrameRenderer::Pending {
    FrameResult out;
    CameraFrame cam{};
    RenderMode mode = RenderMode::Hybrid;
    int frame = 0;
    SharedVector<std::uint32_t> visible; ///< the entities visible in this frame
    double hostMs = 0.0;                 ///< the frame's host time in submit()
    SnapshotCacheCounters cacheBefore, cacheAfter;
    /// The Vulkan half in flight, and whether it holds a far pass.
    std::optional<VulkanFrameInFlight> gpu;
    bool gpuHasFar = false;
};

void FrameRenderer::PendingDeleter::operator()(Pending* p) const {
    if (p && p->gpu) (void)finishVulkanFrame(std::move(*p->gpu)); // never leave a frame in flight
    delete p;
}

FrameResult FrameRenderer::render(double time, RenderMode mode, int frame) {
    return finish(submit(time, mode, frame));
}

FrameRenderer::PendingFrame FrameRenderer::submit(double time, RenderMode mode, int frame,
                                                  const std::function<void()>& selected) {
    // Auto's one-time probe of the Vulkan loader (lavapipe's instance alone takes ~0.1 s) is not
    // part of any frame's time: a hybrid frame decides before the clock starts.
    if (mode == RenderMode::Hybrid) (void)nearBackend();
    if (mode == RenderMode::Hybrid || mode == RenderMode::Far) (void)farBackend();
    const auto t0 = Clock::now();
    PendingFrame pending(new Pending);
    pending->mode = mode;
    pending->frame = frame;
    FrameResult& out = pending->out;
    FrameStats& st = out.stats;

    // 1. Camera and per-entity sprite set-up (CONTRACT.md §3: double precision, camera-relative),
    // kept from the frame before where neither the entity nor the camera changed.
    const CameraFrame cam = makeCameraFrame(scene_.cameraAt(time));
    // Only a hybrid or far frame plans from the store's selection inputs.
    const SpriteStore::Update setup =
        sprites_.update(scene_, cam, time, mode == RenderMode::Hybrid || mode == RenderMode::Far);
    out.sprites = sprites_.shareSprites();
    pending->visible = sprites_.shareVisibleIds();
    st.entities = setup.entities;
    st.culled = setup.culled;
    st.hostSetupMs = msSince(t0);

    // 2. Select each entity's tier (CONTRACT.md §5), its cross-fade and its far view.
    const auto t1 = Clock::now();
    out.plan = planEntities(mode, st);
    st.hostSelectMs = msSince(t1);
    if (selected) selected();

    // 3-5. Near sprites, then far sprites (lazy bakes, blit), composed by min-z: drawn here, or,
    // wholly on Vulkan, submitted here and read back by finish().
    pending->cam = cam;
    pending->cacheBefore = cache_->counters();
    const SpriteHistory history = sprites_.history();
    out.image = drawWith(nearBackendFor(mode, options_.nearBackend), cam, out.sprites, out.plan, st,
                         std::nullopt, sprites_.visibleIds(), pending.get(), &history);
    pending->cacheAfter = cache_->counters();
    pending->hostMs = msSince(t0);
    return pending;
}

FrameResult FrameRenderer::finish(PendingFrame pending) {
    const auto t0 = Clock::now();
    FrameResult& out = pending->out;
    FrameStats& st = out.stats;
    const CameraFrame& cam = pending->cam;
    const RenderMode mode = pending->mode;
    const int frame = pending->frame;
    const SnapshotCacheCounters& cacheBefore = pending->cacheBefore;
    const SnapshotCacheCounters& cacheAfter = pending->cacheAfter;
    if (pending->gpu) {
        out.image = finishOnVulkan(std::move(*pending->gpu), pending->gpuHasFar, st);
        pending->gpu.reset();
    }

    // 6. Where no sprite drew: the ground plane, or a (transparent) background.
    drawBackdrop(scene_, cam, out.image);

    // Debugging and measurement outputs.
    if (options_.overlay) out.overlay = tierOverlay(out.image, out.plan);
    // What the frame cost, to the planner's cost model: the bake time with the cache's split of
    // it (the cost model counts only the bakes' share), and the near tier's fixed cost, measured
    // here by drawing nothing, should the model ask for it.
    FrameCostSample sample;
    sample.bakes = int(st.far.bakes);
    sample.bakeMs = st.far.ensureMs;
    sample.bakeWorkMs = cacheAfter.bakeMs - cacheBefore.bakeMs;
    sample.sceneAndStoreMs =
        (cacheAfter.sceneMs - cacheBefore.sceneMs) + (cacheAfter.storeMs - cacheBefore.storeMs);
    sample.nearMs = st.nearMs;
    sample.nearUploadMs = st.vulkanNear.uploadMs;
    sample.blitMs = st.far.blit.milliseconds + st.vulkan.farPassMs;
    sample.farSnapshotsMs = st.vulkan.farSnapshotsMs;
    sample.planMs = st.hostSelectMs;
    sample.planned =
        mode == RenderMode::Hybrid && scene_.selector.metric == SelectorMetric::ErrorBudget;
    // This frame's visible entities: with frames in flight the store already holds a later one.
    planner_.observe(out.sprites, pending->visible, out.plan, sample, options_.nearRate,
                     [&] { return nearFixedMs(cam, nearBackendFor(mode, options_.nearBackend)); });
    st.cacheBytes = cache_->counters().bytes;
    // The frame's own host time: its two halves, not what ran between them.
    st.totalMs = pending->hostMs + msSince(t0);
    // Pops are measured outside the frame's time: the CPU reference stands in for Vulkan (the
    // same image by contract, and a few sprites are cheap).
    if (options_.measurePops)
        out.pops =
            measurePops(scene_, cam, out.sprites, previousPlan_, out.plan, frame,
                        [&](const auto& sprites, const auto& plan) {
                            FrameStats unused;
                            return drawWith(NearBackend::Reference, cam, sprites, plan, unused);
                        });
    // Kept only for the next frame's pops: a share held across frames costs the planner a copy.
    previousPlan_ = options_.measurePops ? out.plan : SharedVector<EntityPlan>{};
    return std::move(out);
}

SharedVector<EntityPlan> FrameRenderer::planEntities(RenderMode mode, FrameStats& st) {
    PlanSettings settings;
    settings.mode = mode == RenderMode::Reference || mode == RenderMode::Near ? PlanMode::AllNear
                    : mode == RenderMode::Far                                 ? PlanMode::AllFar
                                                                              : PlanMode::Hybrid;
    settings.costAwareBakes = options_.costAwareBakes;
    settings.bakeCosts = options_.bakeCosts;
    settings.inMemory = [&](const SpriteSetup& s, ViewId v) {
        return cache_->inMemory(*scene_.models.at(std::size_t(s.model)), s.frame, v,
                                s.lattice.sigma * cache_->snapshotScale());
    };
    // Without an on-disk store, what the cache has without a bake is what it has in memory,
    // which the planner asks first: no second question (under the error budget at 100,000 tanks,
    // two more locked lookups for each of ~5,000 entities waiting for a bake, one after another).
    if (cache_->config().store)
        settings.withoutBake = [&](const SpriteSetup& s, ViewId v) {
            return cache_->availableWithoutBake(*scene_.models.at(std::size_t(s.model)), s.frame, v,
                                                s.lattice.sigma * cache_->snapshotScale());
        };
    // The planner keeps the cache's answers from frame to frame and asks again about the
    // snapshots the cache baked, loaded or dropped since (most of a moving frame's ~25,000
    // questions at 100,000 tanks are the frame before's). An edit or a new model answers for
    // other keys: a new epoch, every answer asked afresh.
    bool modelsChanged = answeredModels_.size() != scene_.models.size();
    answeredModels_.resize(scene_.models.size());
    for (std::size_t m = 0; m < scene_.models.size(); ++m) {
        const std::pair model{scene_.models[m]->uid(), scene_.models[m]->version()};
        modelsChanged = modelsChanged || answeredModels_[m] != model;
        answeredModels_[m] = model;
    }
    if (modelsChanged) ++answersEpoch_;
    settings.inMemoryEpoch = answersEpoch_;
    if (options_.keepCacheAnswers)
        settings.inMemoryChangesSince = [&](std::optional<std::uint64_t> since,
                                            std::vector<CachedView>& changed) {
            if (since) {
                const auto count = cache_->inMemoryChangesSince(*since, [&](const SnapshotKey& k) {
                    // Only the models' current versions are asked about.
                    for (std::size_t m = 0; m < answeredModels_.size(); ++m)
                        if (answeredModels_[m] == std::pair{k.modelUid, k.version})
                            changed.push_back({int(m), k.frame, k.view});
                });
                if (count) return PlanSettings::InMemoryChanges{*count, true};
            }
            return PlanSettings::InMemoryChanges{cache_->inMemoryChangeCount(), false};
        };
    PlanStats ps;
    SharedVector<EntityPlan> plan =
        planner_.plan(sprites_.sprites(), sprites_.visibleIds(), scene_.selector, settings, ps,
                      sprites_.reposed(), sprites_.selectionInputs());
    st.plan = ps;
    return plan;
}

double FrameRenderer::nearFixedMs(const CameraFrame& cam, NearBackend nearBackend) {
    const bool vulkan = resolved(nearBackend) == NearBackend::Vulkan && near_;
    if (nearFixed_.ms >= 0.0 && nearFixed_.vulkan == vulkan && nearFixed_.width == cam.width &&
        nearFixed_.height == cam.height)
        return nearFixed_.ms;
    // Measured once (per backend and image size): the near tier drawing no sprite. The least of
    // three, since the first may still be warming caches.
    double least = std::numeric_limits<double>::infinity();
    for (int k = 0; k < 3; ++k) {
        const auto t0 = Clock::now();
        if (vulkan) {
            NearOptions no;
            no.rate = options_.nearRate;
            no.pixels = options_.nearPixels;
            no.records = options_.nearRecords;
            (void)near_->render(cam, scene_.models, std::span<const SpriteSetup* const>{},
                                scene_.render.background, no, nullptr);
        } else {
            (void)Image(cam.width, cam.height, scene_.render.background);
        }
        least = std::min(least, msSince(t0));
    }
    nearFixed_ = {least, vulkan, cam.width, cam.height};
    return least;
}

Image FrameRenderer::draw(const CameraFrame& cam, std::span<const SpriteSetup> sprites,
                          std::span<const EntityPlan> plan, FrameStats* stats,
                          std::optional<Tier> onlyTier) {
    FrameStats local;
    return drawWith(options_.nearBackend, cam, sprites, plan, stats ? *stats : local, onlyTier);
}

Image FrameRenderer::drawWith(NearBackend nearBackend, const CameraFrame& cam,
                              std::span<const SpriteSetup> sprites,
                              std::span<const EntityPlan> plan, FrameStats& st,
                              std::optional<Tier> onlyTier, std::span<const std::uint32_t> visible,
                              Pending* pending, const SpriteHistory* history) {
    std::vector<std::uint32_t> found;
    if (visible.empty()) {
        for (std::size_t i = 0; i < sprites.size(); ++i)
            if (sprites[i].visible()) found.push_back(std::uint32_t(i));
        visible = found;
    }
    if (!shares_) shares_ = std::make_unique<TierShares>();
    TierShares& shares = *shares_;
    shares.fill(sprites, plan, visible, onlyTier);
    st.nearDrawn = int(shares.near.size());
    st.farDrawn = int(shares.far.size());
    const std::vector<const SpriteSetup*>& nearSprites = shares.nearSprites;
    if (!shares.far.empty() && farBackend() == FarBackend::Vulkan) {
        // One Vulkan frame draws the near sprites and, after them, the far ones into the same
        // planes with the min-z/id rule; every needed snapshot is made sure of first (lazy
        // bakes, parallel over distinct snapshots). With the near sprites on Vulkan too, the near
        // passes are submitted before that, and the host bakes while the device draws them
        // (GpuFrame::submitSoFar); the far pass is recorded and submitted after. Near sprites
        // drawn by the CPU reference are composed with the Vulkan far image by the same rule.
        FarBatch& batch = shares.farBatch;
        // Nothing holds this frame's snapshots past it but the cache and the device's copies
        // (FarSnapshotCells::owner: a device copy goes once nobody else holds its snapshot).
        struct LetGo {
            FarBatch& batch;
            ~LetGo() { batch.snapshots.clear(); }
        } letGo{batch};
        const auto prepare = [&]() -> const FarBatch* {
            const auto t0 = Clock::now();
            FarFrameStats fs;
            prepareFarBatch(scene_.models, shares.farRequests, *cache_,
                            viewSetFromSize(scene_.selector.viewSetSize), batch, shares.farScratch,
                            &fs);
            st.far = fs;
            st.farMs += msSince(t0);
            return &batch;
        };
        st.farOnVulkan = 1;
        if (!nearSprites.empty() && resolved(nearBackend) == NearBackend::Vulkan)
            return drawOnVulkan(cam, nearSprites, nullptr, colourOnly(), st, pending, history,
                                prepare);
        prepare();
        if (nearSprites.empty())
            return drawOnVulkan(cam, nearSprites, &batch, colourOnly(), st, pending, history);
        Image image = drawNearCpu(cam, nearSprites, st);
        const Image far = drawOnVulkan(cam, {}, &batch, false, st);
        composeMinZ(image, far);
        return image;
    }
    // 3. Near tier: one Vulkan frame (or the CPU reference). The CPU blit below composes on the
    // near image's depth and ids. Without far sprites the Vulkan frame is the whole frame: it is
    // only submitted here, and finish() reads it back (or, with readBack off, times it unread).
    const bool onVulkan = !nearSprites.empty() && resolved(nearBackend) == NearBackend::Vulkan;
    if (onVulkan && !shares.far.empty() && !options_.occlusionCull) {
        // 4 while 3 is on the device: the far snapshots are looked up and baked while the device
        // draws the near sprites, and blitted once their image is read back (the blit composes
        // on its depth and ids). One after the other, a GPU frame waited for the device, then
        // baked (the H200's tank army hybrid: 0.78 ms of wait, then its far tier). The same
        // image: the same snapshots, blitted the same way. Occlusion culling looks up a run of
        // sprites at a time against what the runs before drew, the near image included.
        VulkanFrameInFlight inFlight =
            submitOnVulkan(cam, nearSprites, nullptr, false, true, st, history);
        FarDraws draws; // its lookups' time counts in the far tier's (blitFar)
        try {
            draws = fetchFarSnapshots(scene_.models, shares.farRequests, *cache_,
                                      viewSetFromSize(scene_.selector.viewSetSize));
        } catch (...) { // a bake that failed: the frame in flight still holds its slot
            (void)finishVulkanFrame(std::move(inFlight));
            throw;
        }
        Image image = finishOnVulkan(std::move(inFlight), false, st);
        blitFar(draws, image, st);
        return image;
    }
    Pending* const unread = shares.far.empty() ? pending : nullptr;
    Image image = onVulkan ? drawOnVulkan(cam, nearSprites, nullptr,
                                          shares.far.empty() && colourOnly(), st, unread, history)
                           : drawNearCpu(cam, nearSprites, st);
    // 4-5. Far tier: make sure every needed snapshot exists (lazy bakes, parallel over distinct
    // snapshots), then blit into the same image; the blit writes with the shared min-z/id rule,
    // which is the composition (composeMinZ is the same rule for two finished images).
    if (!shares.far.empty()) drawFar(shares.farRequests, image, st);
    return image;
}

Image FrameRenderer::drawOnVulkan(const CameraFrame& cam,
                                  const std::vector<const SpriteSetup*>& sprites,
                                  const FarBatch* far, bool colourOnly, FrameStats& st,
                                  Pending* pending, const SpriteHistory* history,
                                  const std::function<const FarBatch*()>& farAfterNear) {
    // Only a frame drawn wholly on Vulkan may skip its readback: a CPU tier composes on it.
    VulkanFrameInFlight inFlight = submitOnVulkan(
        cam, sprites, far, colourOnly, options_.readBack || !pending, st, history, farAfterNear);
    const bool hasFar = far != nullptr || bool(farAfterNear);
    if (pending) {
        pending->gpu = std::move(inFlight);
        pending->gpuHasFar = hasFar;
        return Image();
    }
    return finishOnVulkan(std::move(inFlight), hasFar, st);
}

VulkanFrameInFlight FrameRenderer::submitOnVulkan(
    const CameraFrame& cam, const std::vector<const SpriteSetup*>& sprites, const FarBatch* far,
    bool colourOnly, bool readBack, FrameStats& st, const SpriteHistory* history,
    const std::function<const FarBatch*()>& farAfterNear) {
    VulkanFrameRequest request;
    request.camera = &cam;
    request.models = &scene_.models;
    request.nearSprites = sprites;
    request.history = history;
    request.far = far;
    request.farAfterNear = farAfterNear;
    request.clear = scene_.render.background;
    request.near.countSteps = options_.nearCountSteps;
    request.near.rate = options_.nearRate;
    request.near.pixels = options_.nearPixels;
    request.near.records = options_.nearRecords;
    request.near.earlyDepthTest = options_.earlyDepthTest;
    request.near.skipEmpty = options_.nearSkipEmpty;
    request.depthAndIds = !colourOnly;
    request.readBack = readBack;
    if (colourOnly) {
        // One plane read back. The backdrop then finds the pixels no sprite drew by their alpha
        // (sprites always write 255): the planes start as a transparent background where it
        // must fill in an opaque one (the ground).
        const Rgba8 bg = scene_.render.background;
        if (scene_.ground && channel(bg, 3) == 255) request.clear = bg & 0x00FFFFFFu;
    }
    st.nearOnVulkan = st.nearOnVulkan || !sprites.empty();
    return submitVulkanFrame(nearRenderer(), far || farAfterNear ? &farPass() : nullptr, request);
}

Image FrameRenderer::finishOnVulkan(VulkanFrameInFlight&& inFlight, bool hasFar, FrameStats& st) {
    const auto tFinish = Clock::now();
    VulkanFrameResult r = finishVulkanFrame(std::move(inFlight));
    // The Vulkan frame's host time: recording it and finishing it (not what ran in between).
    const double wallMs = r.report.recordMs + msSince(tFinish);
    // The far pass's share of the frame: its recording and its device time.
    const double farShare = hasFar ? r.farRecordMs + r.report.ms("far_upload").value_or(0.0) +
                                         r.report.ms("far_blit").value_or(0.0)
                                   : 0.0;
    st.farMs += farShare;
    st.nearMs += std::max(0.0, wallMs - farShare);
    st.vulkanNear = r.near;
    st.vulkanFar = r.far;
    st.vulkan = timesOf(r.report);
    st.vulkan.farPassMs = farShare;
    st.vulkan.farSnapshotsMs =
        hasFar ? r.far.snapshotUploadMs + r.report.ms("far_snapshots").value_or(0.0) : 0.0;
    st.vulkan.hostRecordFarMs = hasFar ? r.farRecordMs : 0.0;
    return std::move(r.image);
}

Image FrameRenderer::drawNearCpu(const CameraFrame& cam,
                                 const std::vector<const SpriteSetup*>& sprites, FrameStats& st) {
    const auto t0 = Clock::now();
    Image image(cam.width, cam.height, scene_.render.background);
    ReferenceStats rs;
    ReferenceOptions ro;
    ro.rate = options_.nearRate;
    ro.occlusionCull = options_.occlusionCull;
    ro.earlyDepthTest = options_.earlyDepthTest;
    ro.progress = options_.nearProgress;
    renderReference(scene_.models, sprites, image, &rs, ro);
    st.reference = rs;
    st.nearMs += msSince(t0);
    return image;
}

void FrameRenderer::drawFar(const std::vector<FarRequest>& requests, Image& image, FrameStats& st) {
    FarFrameStats fs;
    FarBlitOptions blit = options_.farBlit;
    blit.occlusionCull = options_.occlusionCull;
    drawFarSprites(scene_.models, requests, *cache_, viewSetFromSize(scene_.selector.viewSetSize),
                   image, &fs, blit);
    st.far = fs;
    st.farMs += fs.ensureMs + fs.blit.milliseconds;
}

void FrameRenderer::blitFar(const FarDraws& draws, Image& image, FrameStats& st) {
    FarFrameStats fs;
    blitFarDraws(draws, image, &fs, options_.farBlit);
    st.far = fs;
    st.farMs += fs.ensureMs + fs.blit.milliseconds;
}

Image FrameRenderer::tierOverlay(const Image& image, std::span<const EntityPlan> plan) const {
    // Near entities tinted blue, far ones orange, cross-fading ones green (compose/tier_legend.hpp:
    // no tinted near or far pixel can take that colour); outlines stay black.
    Image o = image;
    tbb::parallel_for(std::size_t(0), o.pixelCount(), [&](std::size_t p) {
        const std::uint32_t e = o.id[p];
        if (e == kernel::VT_NO_ENTITY || e >= plan.size() || o.color[p] == kernel::VT_OUTLINE_RGBA)
            return;
        const Rgba8 c = o.color[p];
        if (plan[e].fade > 0.0f) {
            o.color[p] = tintFading(c);
            return;
        }
        const Rgba8 t = kTierTints[std::size_t(plan[e].tier)];
        o.color[p] =
            packRgba((channel(c, 0) + channel(t, 0)) / 2, (channel(c, 1) + channel(t, 1)) / 2,
                     (channel(c, 2) + channel(t, 2)) / 2, 255);
    });
    drawTierLegend(o);
    return o;
}

void composeMinZ(Image& near, const Image& far) {
    tbb::parallel_for(std::size_t(0), near.pixelCount(), [&](std::size_t p) {
        if (far.id[p] != kernel::VT_NO_ENTITY)
            near.writeIfNearer(p, far.color[p], far.depth[p], far.id[p]);
    });
}

} // namespace voxtier
