// Pops (compose/pop_measure.hpp, issue 38): the seen measure is exactly the whole frame drawn with
// the entity's previous plan against its new one, occlusion included, so that a switch behind
// another entity pops unseen; the summary counts what the events say.
#include "compose/backdrop.hpp"
#include "compose/frame.hpp"
#include "compose/pop_measure.hpp"
#include "core/procedural.hpp"
#include "frame_test_support.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>

namespace voxtier {
namespace {

CameraKey key(double t, double z) {
    CameraKey k;
    k.time = t;
    k.position = {0.0, 1.0, z};
    k.target = {0.0, 0.5, -20.0};
    return k;
}

constexpr std::uint32_t kHidden = 1, kBeside = 2; // entity 0 is the wall

/// A wall, an arrow right behind it (hidden from every camera on the path) and one beside it,
/// both turned so that their far snapshots differ from their near sprites; the camera backs away
/// along +Z past the tier thresholds and comes back, so that every entity switches to far and
/// back to near.
Scene wallScene() {
    Scene s;
    s.render.sigma = 1.0;
    s.render.voxelSize = 0.1;
    s.models = {makeBox({40, 4, 30}), makeArrow(16)};
    const glm::dvec3 at[] = {{0.0, 0.0, -6.0}, {0.0, 0.0, -9.0}, {5.0, 0.0, -9.0}};
    const double turn[] = {0.3, 0.7, 0.35}; // radians about +Y
    for (int i = 0; i < 3; ++i) {
        Entity e;
        e.model = i == 0 ? 0 : 1;
        e.position = at[i];
        e.rotation = glm::angleAxis(turn[i], glm::dvec3(0, 1, 0));
        s.entities.push_back(e);
    }
    s.camera.width = 160;
    s.camera.height = 120;
    s.camera.fovYDeg = 50.0;
    CameraPath path;
    path.fps = 10;
    path.keys = {key(0, 2.0), key(3, 30.0), key(6, 2.0)};
    s.path = path;
    s.selector.nearAt = 14.0;
    s.selector.farAt = 16.0;
    s.ground = GroundPlane{}; // what a pixel an entity leaves shows, where no other entity is
    return s;
}

// For every switch on the path, the seen change is the count of pixels whose colour differs
// between the whole frame drawn with the entity's previous plan and with its new one (every
// entity drawn, with the ground behind them); the hidden arrow's switches change the arrow but
// nothing seen.
TEST(PopMeasure, SeenIsTheWholeFrameDrawnBothWaysOcclusionIncluded) {
    Scene s = wallScene();
    FrameOptions o = test::cpuNear();
    o.measurePops = true;
    FrameRenderer r(s, o);
    std::vector<EntityPlan> previous;
    std::size_t events = 0, hiddenEvents = 0, seenEvents = 0;
    for (int f = 0; f < s.path->frameCount(); ++f) {
        const FrameResult fr = r.render(s.timeOfFrame(f), RenderMode::Hybrid, f);
        const CameraFrame cam = makeCameraFrame(s.cameraAt(s.timeOfFrame(f)));
        for (const PopEvent& e : fr.pops) {
            ++events;
            ASSERT_EQ(previous.size(), fr.plan.size());
            std::vector<EntityPlan> before = fr.plan.copy();
            before[e.entity] = previous[e.entity];
            Image a = r.draw(cam, fr.sprites, before);
            Image b = r.draw(cam, fr.sprites, fr.plan);
            drawBackdrop(s, cam, a);
            drawBackdrop(s, cam, b);
            std::size_t differing = 0;
            for (std::size_t p = 0; p < a.pixelCount(); ++p) differing += a.color[p] != b.color[p];
            EXPECT_EQ(e.seenChangedPixels, differing) << "frame " << f << " entity " << e.entity;
            EXPECT_LE(e.seenDisplacementPx, e.displacementPx) << "frame " << f;
            seenEvents += differing > 0;
            if (e.entity == kHidden) {
                ++hiddenEvents;
                EXPECT_GT(e.changedPixels, 0u) << "frame " << f << ": the arrow itself changes";
                EXPECT_EQ(e.seenChangedPixels, 0u) << "frame " << f;
                EXPECT_EQ(e.seenDisplacementPx, 0.0) << "frame " << f;
            }
        }
        previous = fr.plan.copy();
    }
    EXPECT_GE(hiddenEvents, 2u) << "the hidden arrow should switch to far and back";
    EXPECT_GT(seenEvents, 0u) << "the wall and the arrow switch in sight";
    EXPECT_GT(events, hiddenEvents);
}

// Where nothing else is drawn near the entity and there is no ground, what is seen to change is
// what changes in the entity alone.
TEST(PopMeasure, AnEntityInTheOpenIsSeenAsItIsAlone) {
    Scene s = wallScene();
    s.ground.reset();
    FrameOptions o = test::cpuNear();
    o.measurePops = true;
    FrameRenderer r(s, o);
    std::size_t checked = 0;
    for (int f = 0; f < s.path->frameCount(); ++f)
        for (const PopEvent& e : r.render(s.timeOfFrame(f), RenderMode::Hybrid, f).pops) {
            if (e.entity != kBeside) continue;
            EXPECT_EQ(e.seenChangedPixels, e.changedPixels) << "frame " << f;
            EXPECT_EQ(e.seenDisplacementPx, e.displacementPx) << "frame " << f;
            ++checked;
        }
    EXPECT_GE(checked, 2u);
}

PopEvent event(PopEvent::Kind kind, std::size_t seenPixels, double seenPx, double vpxPx) {
    PopEvent e;
    e.kind = kind;
    e.seenChangedPixels = seenPixels;
    e.seenDisplacementPx = seenPx;
    e.vpxPx = vpxPx;
    return e;
}

// The summary's counts, worst cases and threshold; a virtual pixel smaller than a screen pixel
// counts as one (a one-pixel move is never more than one).
TEST(PopMeasure, SummaryCountsSwitchesWorstCasesAndTheThreshold) {
    PopSummary s(16);
    s.add(event(PopEvent::Kind::TierSwitch, 16, 2.0, 4.0)); // 0.5 vpx, at the threshold
    s.add(event(PopEvent::Kind::ViewSwitch, 0, 0.0, 2.0));
    s.add(event(PopEvent::Kind::ViewSwitch, 17, 3.0, 0.25)); // 3 vpx: screen pixels
    s.add(event(PopEvent::Kind::FadeStep, 900, std::numeric_limits<double>::infinity(), 3.0));
    EXPECT_EQ(s.events, 4u);
    EXPECT_EQ(s.tierSwitches, 1u);
    EXPECT_EQ(s.viewSwitches, 2u);
    EXPECT_EQ(s.fadeSteps, 1u);
    EXPECT_EQ(s.seen, 3u);
    EXPECT_EQ(s.overThreshold, 2u);
    EXPECT_EQ(s.worstPixels, 900u);
    EXPECT_EQ(s.worstVpx, 3.0);
    EXPECT_EQ(s.appearing, 1u);
}

} // namespace
} // namespace voxtier
