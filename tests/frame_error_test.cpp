// The bench's error measurements (compose/frame_error.hpp): the per-tier summary of a frame, the
// far tier's error measured on each entity alone, and the size of a virtual pixel on screen.
// Expectations come from closed forms and from the far tier's exactness at canonical views.
#include "compose/error_metrics.hpp"
#include "compose/frame.hpp"
#include "compose/frame_error.hpp"
#include "core/procedural.hpp"
#include "frame_test_support.hpp"

#include <gtest/gtest.h>

#include <cmath>

namespace voxtier {
namespace {

using test::cpuNear;

Entity at(int model, glm::dvec3 p, double yawDeg) {
    Entity e;
    e.model = model;
    e.position = p;
    e.rotation = glm::angleAxis(glm::radians(yawDeg), glm::dvec3(0, 1, 0));
    return e;
}

/// A tank in front of (nearer than) an arrow, overlapping it on screen, both in view.
Scene overlapping(double tankYaw) {
    Scene s;
    s.models = {makeTank(2, 1), makeArrow(16)};
    s.entities = {at(1, {0.3, 0.2, -9.0}, 33.0), at(0, {0.0, 0.0, -6.0}, tankYaw)};
    s.camera.position = {0, 1.5, 0};
    s.camera.target = {0, 0.3, -8};
    s.camera.width = 320;
    s.camera.height = 200;
    return s;
}

TEST(FrameError, CellSizeIsOneVoxelOnScreenOverSigma) {
    // An entity on the optical axis: a voxel at view depth z covers voxelSize * focalPx / z pixels.
    for (double sigma : {1.0, 2.0, 0.5}) {
        Scene s;
        s.render.sigma = sigma;
        s.models = {makeBox({8, 8, 8})};
        s.entities = {at(0, {0, -0.4, -10}, 0)}; // centre at the origin's height: on the axis
        s.camera.position = {0, 0, 0};
        s.camera.target = {0, 0, -1};
        const CameraFrame cam = makeCameraFrame(s.camera);
        const auto sprites = setupSprites(s, cam, 0.0);
        ASSERT_TRUE(sprites[0].visible());
        const double expected = s.render.voxelSize * cam.focalPx() / 10.0 / sigma;
        EXPECT_NEAR(cellSizePx(sprites[0]), expected, 1e-9 * expected) << sigma;
    }
}

TEST(FrameError, AllFarFrameOfCanonicalViewsHasNoError) {
    // Parallel rays straight down on entities turned by quarter turns: every sprite's view is
    // the +Z snapshot, where the far tier equals the near tier exactly (DESIGN.md §4).
    Scene s;
    s.render.viewMode = ViewMode::Parallel;
    s.models = {makeTank(4, 1), makeArrow(16)};
    for (int k = 0; k < 6; ++k)
        s.entities.push_back(at(k % 2, {-3.0 + 1.5 * k, 0, (k % 3) - 1.0}, 90.0 * k));
    s.camera.position = {0, 12, 0};
    s.camera.target = {0, 0, 0};
    s.camera.up = {0, 0, -1};
    s.camera.width = 256;
    s.camera.height = 160;
    FrameRenderer r(s, cpuNear());
    const FrameResult truth = r.render(0.0, RenderMode::Reference);
    const FrameResult far = r.render(0.0, RenderMode::Far);
    const FrameErrorReport e = measureFrameError(truth.image, far.image, far.sprites, far.plan);
    EXPECT_EQ(e.all.entities, 6u);
    EXPECT_EQ(e.far.entities, 6u);
    EXPECT_EQ(e.differingPixels, 0u);
    EXPECT_EQ(e.all.worstMismatch, 0.0);
    const auto alone =
        isolatedFarErrors(s, makeCameraFrame(s.camera), far.sprites, far.plan, r.snapshotCache());
    ASSERT_EQ(alone.size(), 6u);
    for (const EntityError& a : alone) {
        EXPECT_EQ(a.mismatched, 0u) << a.entity;
        EXPECT_EQ(a.silhouetteDisplacementPx, 0.0) << a.entity;
    }
    // The near frame compared with itself: nothing is far, nothing differs.
    const FrameErrorReport self =
        measureFrameError(truth.image, truth.image, truth.sprites, truth.plan);
    EXPECT_EQ(self.far.entities, 0u);
    EXPECT_EQ(self.differingPixels, 0u);
}

TEST(FrameError, AloneErrorOfAFarEntityIgnoresWhatStandsInFrontOfIt) {
    // The arrow is far in both frames; the tank in front of it is drawn near in one and far in
    // the other. The arrow's visible footprint changes with the tank, its error alone does not.
    Scene s = overlapping(20.0);
    FrameRenderer r(s, cpuNear());
    const CameraFrame cam = makeCameraFrame(s.camera);
    const FrameResult truth = r.render(0.0, RenderMode::Reference);
    const FrameResult far = r.render(0.0, RenderMode::Far);
    std::vector<EntityPlan> arrowFar = far.plan.copy();
    arrowFar[1].tier = Tier::Near; // the tank near, the arrow far
    arrowFar[1].view.reset();
    const Image mixed = r.draw(cam, far.sprites, arrowFar);

    const auto aloneAll = isolatedFarErrors(s, cam, far.sprites, far.plan, r.snapshotCache());
    const auto aloneMixed = isolatedFarErrors(s, cam, far.sprites, arrowFar, r.snapshotCache());
    ASSERT_EQ(aloneAll.size(), 2u);
    ASSERT_EQ(aloneMixed.size(), 1u);
    EXPECT_EQ(aloneMixed[0].entity, 0u);
    EXPECT_EQ(aloneAll[0].entity, 0u);
    EXPECT_EQ(aloneMixed[0].mismatched, aloneAll[0].mismatched);
    EXPECT_EQ(aloneMixed[0].unionPixels, aloneAll[0].unionPixels);
    EXPECT_EQ(aloneMixed[0].silhouetteDisplacementPx, aloneAll[0].silhouetteDisplacementPx);
    // The arrow is seen well away from any snapshot view, so the far tier does change it.
    EXPECT_GT(aloneAll[0].mismatched, 0u);

    // In the frames, the arrow's visible footprint depends on what the tank looks like.
    const FrameErrorReport inAll = measureFrameError(truth.image, far.image, far.sprites, far.plan);
    const FrameErrorReport inMixed = measureFrameError(truth.image, mixed, far.sprites, arrowFar);
    EXPECT_EQ(inMixed.far.entities, 1u);
    EXPECT_EQ(inAll.far.entities, 2u);
    const EntityError visibleAll = entityError(truth.image, far.image, 0),
                      visibleMixed = entityError(truth.image, mixed, 0);
    EXPECT_NE(visibleAll.footprintTest, visibleMixed.footprintTest);
    // Summaries of the alone errors use the entities' own cell sizes.
    const EntityErrorSummary sum = summarizeEntities(aloneAll, far.sprites);
    EXPECT_EQ(sum.entities, 2u);
    EXPECT_GE(sum.worstDisplacementPx,
              sum.worstDisplacementCells); // a virtual pixel is at least one pixel
}

} // namespace
} // namespace voxtier
