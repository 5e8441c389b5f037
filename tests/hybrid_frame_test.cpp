// The hybrid frame (issue 5): tiers handed over without double draws, hysteresis on real camera
// paths, far sprites within the error CONTRACT.md §5 predicts, and popping with / without the
// cross-fade. The near tier is drawn by the CPU reference here (identical to Vulkan by the
// near tier's own suite) so that paths of dozens of frames stay fast.
#include "compose/error_metrics.hpp"
#include "compose/frame.hpp"
#include "core/procedural.hpp"
#include "core/view_set.hpp"
#include "crowd_scenes.hpp"
#include "frame_test_support.hpp"
#include "impostor_cache/far_frame.hpp"
#include "impostor_cache/snapshot_cache.hpp"
#include "volumetric/reference_renderer.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <set>

namespace voxtier {
namespace {

using test::cpuNear;

/// A row of models along -Z, the camera on a path along Z (distance thresholds in metres).
Scene corridor(int count, double spacing, const std::vector<CameraKey>& keys, SelectorConfig sel) {
    Scene s;
    s.render.sigma = 1.0;
    s.render.voxelSize = 0.1;
    s.models = {makeArrow(16), makeBox({6, 8, 10}), makeSphere(5)};
    for (int i = 0; i < count; ++i) {
        Entity e;
        e.model = i % 3;
        e.position = {(i % 2 ? 1.0 : -1.0) * (0.8 + 0.1 * i), 0.0, -spacing * i};
        e.rotation = glm::angleAxis(0.7 * i, glm::dvec3(0, 1, 0));
        s.entities.push_back(e);
    }
    s.camera.width = 240;
    s.camera.height = 160;
    s.camera.fovYDeg = 30.0;
    CameraPath path;
    path.fps = 10;
    path.keys = keys;
    s.path = path;
    s.selector = sel;
    return s;
}

CameraKey key(double t, glm::dvec3 pos, glm::dvec3 target) {
    CameraKey k;
    k.time = t;
    k.position = pos;
    k.target = target;
    return k;
}

SelectorConfig band(double nearAt, double farAt, int crossfade = 0) {
    SelectorConfig c;
    c.nearAt = nearAt;
    c.farAt = farAt;
    c.crossfadeFrames = crossfade;
    return c;
}

// Every visible entity is drawn by exactly one tier, or by both during a cross-fade with
// complementary pixel sets: no pixel of any entity comes from two tiers. Checked in every mode.
TEST(HybridFrame, EveryEntityIsDrawnExactlyOncePerPixelInEveryMode) {
    Scene s = corridor(12, 2.0, {key(0, {0, 1, 6}, {0, 0, -20}), key(3, {0, 1, -6}, {0, 0, -30})},
                       band(6, 9, 4));
    FrameRenderer r(s, cpuNear());
    for (RenderMode mode : {RenderMode::Reference, RenderMode::Far, RenderMode::Hybrid}) {
        int sawFade = 0;
        for (int f = 0; f < s.path->frameCount(); ++f) {
            const double t = s.timeOfFrame(f);
            const FrameResult fr = r.render(t, mode, f);
            const CameraFrame cam = makeCameraFrame(s.cameraAt(t));
            for (std::size_t i = 0; i < fr.plan.size(); ++i) {
                const EntityPlan& p = fr.plan[i];
                sawFade += p.fade > 0.0f;
                EXPECT_TRUE(p.drawsNear() || p.drawsFar());
                EXPECT_EQ(p.drawsNear() && p.drawsFar(), p.fade > 0.0f) << "entity " << i;
            }
            // The frame's near share and far share, drawn separately.
            const Image a = r.draw(cam, fr.sprites, fr.plan, nullptr, Tier::Near);
            const Image b = r.draw(cam, fr.sprites, fr.plan, nullptr, Tier::Far);
            // Composition of the two halves equals the frame (the blit-into-near composition).
            Image composed = a;
            composeMinZ(composed, b);
            EXPECT_TRUE(diffImages(composed, fr.image).identical())
                << toString(mode) << " frame " << f;
            // No pixel shows one entity in both shares (fading entities use complementary masks).
            for (std::size_t p = 0; p < a.pixelCount(); ++p) {
                if (a.id[p] != kernel::VT_NO_ENTITY && a.id[p] == b.id[p]) {
                    ADD_FAILURE() << toString(mode) << " frame " << f << ": entity " << a.id[p]
                                  << " drawn by both tiers at pixel " << p;
                    break;
                }
            }
        }
        if (mode == RenderMode::Hybrid) {
            EXPECT_GT(sawFade, 0) << "the path should exercise cross-fades";
        }
    }
}

// Cross-fading entities: the near half and the far half of one entity, drawn alone, never share
// a pixel, and together they cover what a single tier would (no hole, no double draw).
TEST(HybridFrame, CrossFadeHalvesAreComplementary) {
    Scene s = corridor(3, 2.0, {key(0, {0, 1, 6}, {0, 0, -20})}, band(6, 9, 3));
    FrameRenderer r(s, cpuNear());
    const CameraFrame cam = makeCameraFrame(s.camera);
    const auto sprites = setupSprites(s, cam, 0.0);
    for (std::size_t i = 0; i < sprites.size(); ++i) {
        if (!sprites[i].visible()) continue;
        for (float share : {0.25f, 0.5f, 0.75f}) {
            EntityPlan toFar;
            toFar.tier = Tier::Far;
            toFar.fadeFrom = Tier::Near;
            toFar.fade = share;
            toFar.view =
                viewIdOf(ViewSet::Cube26, nearestView(ViewSet::Cube26, -sprites[i].lattice.dir));
            const std::vector<SpriteSetup> one = {sprites[i]};
            const Image both = r.draw(cam, one, {toFar});
            EntityPlan plainNear, plainFar;
            plainFar.tier = Tier::Far;
            plainFar.view = toFar.view;
            const Image allNear = r.draw(cam, one, {plainNear});
            const Image allFar = r.draw(cam, one, {plainFar});
            // Every pixel of the faded image comes from the near or the far image at that pixel,
            // chosen by the dither threshold.
            for (int y = 0; y < both.height; ++y)
                for (int x = 0; x < both.width; ++x) {
                    const std::size_t p = both.index(x, y);
                    const bool newTier = kernel::vtDitherThreshold({x, y}) < share;
                    const Image& src = newTier ? allFar : allNear;
                    ASSERT_EQ(both.color[p], src.color[p])
                        << "entity " << i << " share " << share << " at " << x << "," << y;
                    ASSERT_EQ(both.id[p], src.id[p]);
                }
        }
    }
}

int countSwitches(Scene& s) {
    FrameRenderer r(s, cpuNear());
    int switches = 0;
    for (int f = 0; f < s.path->frameCount(); ++f) {
        const FrameResult fr = r.render(s.timeOfFrame(f), RenderMode::Hybrid, f);
        switches += fr.stats.plan.switchesToFar + fr.stats.plan.switchesToNear;
    }
    return switches;
}

// CONTRACT.md §5 on a real camera path: oscillating around far_at with an amplitude below
// (far_at - near_at)/2 switches once; a path crossing the band back and forth switches once per
// crossing.
TEST(HybridFrame, CameraPathHysteresis) {
    const double nearAt = 8, farAt = 12;
    {
        std::vector<CameraKey> keys = {key(0, {0, 0.5, -4}, {0, 0, -40})}; // start close: near
        for (int k = 1; k <= 12; ++k)
            keys.push_back(key(k, {0, 0.5, farAt + (k % 2 ? 1.9 : -1.9)},
                               {0, 0, -40})); // +-1.9 m around far_at
        Scene s = corridor(1, 0.0, keys, band(nearAt, farAt));
        EXPECT_EQ(countSwitches(s), 1);
    }
    {
        std::vector<CameraKey> keys;
        for (int k = 0; k <= 6; ++k)
            keys.push_back(key(k, {0, 0.5, k % 2 ? 20.0 : 2.0}, {0, 0, -40}));
        Scene s = corridor(1, 0.0, keys, band(nearAt, farAt));
        EXPECT_EQ(countSwitches(s), 6);
    }
}

/// The far tier's error at a switch, predicted by CONTRACT.md §5: viewing from the snapshot's
/// direction w* instead of the entity's own direction d moves a model point at radius r by at
/// most 2 r sin(theta/2) = r sin(theta) / cos(theta/2) on the sprite plane (theta = angle(d, w*)).
/// Both tiers quantise to the same lattice, which may add one cell diagonal on each side, and
/// pixel sampling one more pixel.
double predictedDisplacementBound(const SpriteSetup& s, double theta, const CameraFrame& cam) {
    const double cellPx = (s.pose.metresPerVoxel / s.lattice.sigma) / s.viewDepth * cam.focalPx();
    return s.radiusPx * std::sin(theta) / std::cos(theta / 2.0) + 2.0 * std::sqrt(2.0) * cellPx +
           1.0;
}

// Far sprites against the ground truth (the all-near render of the same frame): at the frame an
// entity switches to far, its silhouette is displaced by no more than the §5 prediction.
TEST(HybridFrame, FarSpritesStayWithinThePredictedErrorAtTheSwitch) {
    std::vector<CameraKey> keys = {key(0, {0, 0.5, 4}, {0, 0, -30}),
                                   key(4, {0, 3.5, 24}, {0, 0, -30})};
    Scene s = corridor(6, 3.0, keys, band(14, 16));
    FrameRenderer hybrid(s, cpuNear());
    int checked = 0;
    for (int f = 0; f < s.path->frameCount(); ++f) {
        const double t = s.timeOfFrame(f);
        const FrameResult h = hybrid.render(t, RenderMode::Hybrid, f);
        const CameraFrame cam = makeCameraFrame(s.cameraAt(t));
        for (std::size_t i = 0; i < h.plan.size(); ++i) {
            const SpriteSetup& sp = h.sprites[i];
            if (h.plan[i].tier != Tier::Far || !sp.visible()) continue;
            const double theta = std::acos(
                std::clamp(glm::dot(viewDirection(*h.plan[i].view), -sp.lattice.dir), -1.0, 1.0));
            const double bound = predictedDisplacementBound(sp, theta, cam);
            // Alone in both tiers, so other entities' occlusion does not enter the comparison.
            const std::vector<SpriteSetup> one = {sp};
            const Image farAlone = hybrid.draw(cam, one, {h.plan[i]});
            const Image nearAlone = hybrid.draw(cam, one, {EntityPlan{}});
            const EntityError e = entityError(nearAlone, farAlone, std::uint32_t(i));
            EXPECT_LE(e.silhouetteDisplacementPx, bound)
                << "frame " << f << " entity " << i << " theta " << glm::degrees(theta) << " r_px "
                << sp.radiusPx;
            ++checked;
        }
    }
    EXPECT_GT(checked, 10);
}

// The error metric keeps every far entity under its budget: with metric error_px, an entity is
// far only while its predicted error r_px sin(theta) stays below near_at (the band's top).
TEST(HybridFrame, ErrorMetricKeepsEveryFarEntityUnderBudget) {
    SelectorConfig sel =
        defaultSelectorFor(SelectorMetric::ErrorPx); // far below 0.5 px, near above 1.0 px
    std::vector<CameraKey> keys = {key(0, {0, 0.5, 4}, {0, 0, -30}),
                                   key(6, {2, 6, 60}, {0, 0, -30})};
    Scene s = corridor(8, 3.0, keys, sel);
    FrameRenderer r(s, cpuNear());
    int farSeen = 0;
    for (int f = 0; f < s.path->frameCount(); ++f) {
        const FrameResult fr = r.render(s.timeOfFrame(f), RenderMode::Hybrid, f);
        for (std::size_t i = 0; i < fr.plan.size(); ++i) {
            const SpriteSetup& sp = fr.sprites[i];
            if (fr.plan[i].tier != Tier::Far || !sp.visible()) continue;
            ++farSeen;
            const double theta = std::acos(
                std::clamp(glm::dot(viewDirection(*fr.plan[i].view), -sp.lattice.dir), -1.0, 1.0));
            EXPECT_LE(sp.radiusPx * std::sin(theta), sel.nearAt)
                << "frame " << f << " entity " << i;
            // ...and what the far sprite actually shows stays within the error that predicts.
            const CameraFrame cam = makeCameraFrame(s.cameraAt(s.timeOfFrame(f)));
            const std::vector<SpriteSetup> one = {sp};
            const EntityError e = entityError(r.draw(cam, one, {EntityPlan{}}),
                                              r.draw(cam, one, {fr.plan[i]}), std::uint32_t(i));
            EXPECT_LE(e.silhouetteDisplacementPx, predictedDisplacementBound(sp, theta, cam))
                << "frame " << f << " entity " << i;
        }
    }
    EXPECT_GT(farSeen, 5);
}

/// Largest single-frame change a tier switch (or a fade step) causes on its own along a path.
struct PopSummary {
    std::size_t tierEvents = 0, viewEvents = 0;
    std::size_t largestChange = 0;
};
PopSummary pops(Scene& s) {
    FrameOptions o = cpuNear();
    o.measurePops = true;
    FrameRenderer r(s, o);
    PopSummary out;
    for (int f = 0; f < s.path->frameCount(); ++f) {
        const FrameResult fr = r.render(s.timeOfFrame(f), RenderMode::Hybrid, f);
        for (const PopEvent& e : fr.pops) {
            out.tierEvents += e.kind != PopEvent::Kind::ViewSwitch;
            out.viewEvents += e.kind == PopEvent::Kind::ViewSwitch;
            if (e.kind != PopEvent::Kind::ViewSwitch)
                out.largestChange = std::max(out.largestChange, e.changedPixels);
        }
    }
    return out;
}

// A camera flying through both thresholds and across view boundaries produces a popping report;
// with the cross-fade on, the largest per-frame change at a tier switch is smaller.
TEST(HybridFrame, CrossFadeMakesTheLargestSwitchChangeSmaller) {
    std::vector<CameraKey> keys = {key(0, {-3, 0.5, 2}, {0, 0, -20}),
                                   key(4, {6, 4, 22}, {0, 0, -20}),
                                   key(8, {-3, 0.5, 2}, {0, 0, -20})};
    Scene instant = corridor(6, 2.5, keys, band(9, 11, 0));
    Scene faded = corridor(6, 2.5, keys, band(9, 11, 4));
    const PopSummary a = pops(instant);
    const PopSummary b = pops(faded);
    EXPECT_GT(a.tierEvents, 0u);
    EXPECT_GT(a.viewEvents, 0u) << "the path should cross snapshot view boundaries";
    EXPECT_GT(a.largestChange, 0u);
    EXPECT_LT(b.largestChange, a.largestChange);
    std::printf("[ pops     ] largest change at a switch: instant %zu px, cross-fade %zu px (%zu / "
                "%zu tier events, %zu view events)\n",
                a.largestChange, b.largestChange, a.tierEvents, b.tierEvents, a.viewEvents);
}

// Thousands of entities in every kind of share at once (near, far, fading either way, a far view
// fading into another), so that the frame's tier lists are built in many parallel chunks: the
// frame equals its two halves drawn from lists written here serially, each fading entity's half a
// copy that keeps its side of the dither, near by the CPU reference and far by the CPU blit,
// composed by the depth/id rule.
TEST(HybridFrame, TierSharesOfThousandsOfEntitiesEqualTheSharesListedOneByOne) {
    Scene s = test::tankArmy(6000, 320, 180);
    const double t = s.timeOfFrame(3);
    const CameraFrame cam = makeCameraFrame(s.cameraAt(t));
    const std::vector<SpriteSetup> sprites = setupSprites(s, cam, t);
    std::vector<EntityPlan> plan(sprites.size());
    std::mt19937 rng(5);
    int kinds[5] = {};
    for (std::size_t i = 0; i < sprites.size(); ++i) {
        if (!sprites[i].visible()) continue;
        const int nearest = nearestView(ViewSet::Cube26, -sprites[i].lattice.dir);
        const ViewId view = viewIdOf(ViewSet::Cube26, nearest);
        const float share = 0.25f * float(1 + rng() % 3);
        EntityPlan& p = plan[i];
        const int kind = int(rng() % 5);
        ++kinds[kind];
        if (kind == 0) continue; // near
        p.view = view;
        if (kind == 1) p.tier = Tier::Far;
        if (kind == 2) p.tier = Tier::Far, p.fadeFrom = Tier::Near, p.fade = share;
        if (kind == 3) p.tier = Tier::Near, p.fadeFrom = Tier::Far, p.fade = share;
        if (kind == 4) { // a far view fading into the nearest one
            p.tier = Tier::Far, p.fadeFrom = Tier::Far, p.fade = share;
            p.fadeFromView = viewIdOf(ViewSet::Cube26, (nearest + 1) % 26);
        }
    }
    for (const int k : kinds) EXPECT_GT(k, 500);

    // The shares, one entity after another.
    std::vector<SpriteSetup> copies;
    copies.reserve(3 * sprites.size()); // no reallocation: the lists point into it
    const auto share = [&](std::size_t i, const EntityPlan& p, bool keepBelow) {
        if (p.fade <= 0.0f) return &sprites[i];
        SpriteSetup c = sprites[i];
        c.gpu.fade = p.fade;
        c.gpu.fadeSide = keepBelow ? 1.0f : -1.0f;
        copies.push_back(c);
        return static_cast<const SpriteSetup*>(&copies.back());
    };
    std::vector<const SpriteSetup*> nearSprites;
    std::vector<FarRequest> farRequests;
    for (std::size_t i = 0; i < sprites.size(); ++i) {
        if (!sprites[i].visible()) continue;
        const EntityPlan& p = plan[i];
        if (p.drawsNear()) nearSprites.push_back(share(i, p, p.tier == Tier::Near));
        if (p.drawsFar()) farRequests.push_back({share(i, p, p.tier == Tier::Far), p.view});
        if (p.fadeFromView && p.fade > 0.0f)
            farRequests.push_back({share(i, p, false), p.fadeFromView});
    }
    Image nearHalf(cam.width, cam.height, s.render.background);
    renderReference(s.models, nearSprites, nearHalf);
    Image farHalf(cam.width, cam.height, s.render.background);
    SnapshotCache cache;
    drawFarSprites(s.models, farRequests, cache, ViewSet::Cube26, farHalf);
    composeMinZ(nearHalf, farHalf);

    FrameRenderer r(s, cpuNear());
    FrameStats stats;
    const Image frame = r.draw(cam, sprites, plan, &stats);
    EXPECT_EQ(stats.nearDrawn, int(nearSprites.size()));
    EXPECT_EQ(stats.farDrawn, int(farRequests.size()));
    const ImageDiff d = diffImages(nearHalf, frame);
    EXPECT_TRUE(d.identical()) << d.pixelDiffs << " pixels differ, the first at " << d.firstX << ","
                               << d.firstY;
}

// Occlusion culling looks up and blits a run of sprites at a time against what the runs before
// drew: snapshots fetched ahead of the near image cannot be culled, and say so.
TEST(HybridFrame, FarDrawsFetchedAheadRefuseOcclusionCulling) {
    Image target(8, 8, 0u);
    FarBlitOptions culling;
    culling.occlusionCull = true;
    EXPECT_THROW(blitFarDraws(FarDraws{}, target, nullptr, culling), std::invalid_argument);
    EXPECT_NO_THROW(blitFarDraws(FarDraws{}, target, nullptr, FarBlitOptions{}));
}

// The hybrid frame's far half comes from the cache: a second identical frame bakes nothing.
TEST(HybridFrame, SecondFrameReusesSnapshots) {
    Scene s = corridor(10, 3.0, {key(0, {0, 1, 8}, {0, 0, -30})}, band(6, 9));
    FrameRenderer r(s, cpuNear());
    const FrameResult a = r.render(0.0, RenderMode::Hybrid);
    const FrameResult b = r.render(0.0, RenderMode::Hybrid);
    EXPECT_GT(a.stats.farDrawn, 0);
    EXPECT_GT(a.stats.nearDrawn, 0);
    EXPECT_GT(a.stats.far.bakes, 0);
    EXPECT_EQ(b.stats.far.bakes, 0);
    EXPECT_TRUE(diffImages(a.image, b.image).identical());
}

// submit()'s `selected` (what the render command starts its file writer from): once a frame, after
// its set-up and selection and before its drawing, which bakes the far tier's snapshots.
TEST(HybridFrame, SubmitCallsSelectedOnceBetweenSelectionAndDrawing) {
    Scene s = corridor(10, 3.0, {key(0, {0, 1, 8}, {0, 0, -30})}, band(6, 9));
    FrameRenderer r(s, cpuNear());
    int calls = 0;
    std::uint64_t bakesThen = ~std::uint64_t(0);
    FrameRenderer::PendingFrame pending = r.submit(0.0, RenderMode::Hybrid, 0, [&] {
        ++calls;
        bakesThen = r.snapshotCache().counters().bakes;
    });
    EXPECT_EQ(calls, 1);
    EXPECT_EQ(bakesThen, 0u) << "called after the far tier drew";
    const FrameResult a = r.finish(std::move(pending));
    EXPECT_GT(a.stats.far.bakes, 0); // the far tier drew after the call
    EXPECT_GT(a.stats.farDrawn, 0);
    EXPECT_EQ(calls, 1);
    // Without one, the same frame.
    FrameRenderer plain(s, cpuNear());
    EXPECT_TRUE(diffImages(plain.render(0.0, RenderMode::Hybrid).image, a.image).identical());
}

} // namespace
} // namespace voxtier
