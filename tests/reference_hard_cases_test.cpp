// The numerically hard cases of CONTRACT.md §7 / HARD_CASES.md that the CPU reference must meet:
// 10^5-10^6 m from the origin, camera straight down, behind / inside / touching, sub-pixel,
// equal depths, non-integer sigma, thread-count independence.
#include "hard_case_scenes.hpp"
#include "image_checks.hpp"
#include "test_models.hpp"
#include "volumetric/reference_renderer.hpp"

#include <gtest/gtest.h>
#include <tbb/global_control.h>

#include <algorithm>

namespace voxtier {
namespace {

Image render(const Scene& s, std::vector<SpriteSetup>* setups = nullptr) {
    return test::renderReferenceImage(s, setups);
}

// Everything is computed relative to the eye in double before rounding to float, so moving the
// whole world 2^20 m (or 2^17 m) away changes nothing. Offsets are powers of two and positions
// dyadic so that the camera-relative doubles are bit-identical.
TEST(FarFromOrigin, WorldAtOneMillionMetresRendersTheSameImage) {
    const Image origin = render(test::hardCaseWorld(glm::dvec3(0.0)));
    ASSERT_GT(std::count_if(origin.id.begin(), origin.id.end(),
                            [](auto v) { return v != kernel::VT_NO_ENTITY; }),
              1000);
    for (glm::dvec3 offset :
         {glm::dvec3(1048576.0, 0.0, -1048576.0), glm::dvec3(-131072.0, 65536.0, 131072.0)}) {
        const Image far = render(test::hardCaseWorld(offset));
        const ImageDiff d = diffImages(origin, far);
        EXPECT_TRUE(d.identical())
            << "colour " << d.colorDiffs << " depth " << d.depthDiffs << " id " << d.idDiffs;
    }
}

// RTS camera: looking straight down with up = world -Z. The bar's +X end must appear on the
// right and its +Y (world -Z, screen up) marker above the bar's middle: no mirror, no flip.
TEST(CameraStraightDown, TopDownViewIsUprightAndUnmirrored) {
    const Scene s = test::topDownMarkedBar();
    std::vector<SpriteSetup> setups;
    const Image img = render(s, &setups);
    ASSERT_TRUE(setups[0].visible());
    const test::MarkerAndBar c = test::markerAndBarCentres(s, img);
    ASSERT_GT(c.markerPixels, 0) << "marker voxel not visible from above (top face lighting)";
    ASSERT_GT(c.barPixels, 0);
    EXPECT_GT(c.markerX, c.barX + 1.0) << "marker should be right of the bar centre";
    EXPECT_LT(c.markerY, c.barY)
        << "marker (+Y voxel = -Z world = screen up) should be above the bar centre";
}

TEST(Culling, EntityBehindCameraDrawsNothing) {
    const Scene s = test::entityBehindCamera();
    std::vector<SpriteSetup> setups;
    const Image img = render(s, &setups);
    EXPECT_EQ(setups[0].cull, CullReason::BehindCamera);
    EXPECT_EQ(img.countEntity(0), 0u);
}

TEST(Culling, CameraInsideOrTouchingProxyBoxCullsOnlyThatEntity) {
    const Scene s = test::hardCaseWorld(glm::dvec3(0.0));
    const SpriteSetup before = setupSprite(makeCameraFrame(s.camera), s.entities[0], 0,
                                           *s.models[0], 0, s.render, s.light);
    ASSERT_TRUE(before.visible());
    for (const Scene& t : test::eyeInsideAndOnProxyBox()) {
        std::vector<SpriteSetup> setups;
        const Image img = render(t, &setups);
        EXPECT_EQ(setups[0].cull, CullReason::CameraInside);
        EXPECT_EQ(img.countEntity(0), 0u);
        int othersDrawn = 0;
        for (std::uint32_t i = 1; i < setups.size(); ++i) othersDrawn += img.countEntity(i) > 0;
        EXPECT_GE(othersDrawn, 1);
    }
}

TEST(Culling, SubPixelEntityDrawsNothing) {
    const Scene s = test::subPixelEntity();
    std::vector<SpriteSetup> setups;
    const Image img = render(s, &setups);
    EXPECT_LT(setups[0].radiusPx, 0.5);
    EXPECT_EQ(setups[0].cull, CullReason::SubPixel);
    EXPECT_EQ(img.countEntity(0), 0u);
}

// Two overlapping sprites at exactly the same depth: the lower entity id owns every shared
// pixel, whatever order the renderer visits them in.
TEST(EqualDepth, LowerEntityIdWinsRegardlessOfOrder) {
    const Scene s = test::equalDepthPair();
    const CameraFrame cam = makeCameraFrame(s.camera);
    auto sprites = setupSprites(s, cam, 0.0);
    ASSERT_EQ(sprites[0].gpu.depth, sprites[1].gpu.depth);
    Image forward(cam.width, cam.height, 0), backward(cam.width, cam.height, 0);
    renderReference(s.models, std::vector<const SpriteSetup*>{&sprites[0], &sprites[1]}, forward);
    renderReference(s.models, std::vector<const SpriteSetup*>{&sprites[1], &sprites[0]}, backward);
    EXPECT_TRUE(diffImages(forward, backward).identical());
    // In the overlap, entity 0 wins; entity 1 still owns its own part.
    Image only1(cam.width, cam.height, 0);
    renderReference(s.models, std::vector<const SpriteSetup*>{&sprites[1]}, only1);
    std::size_t overlap = 0;
    for (std::size_t p = 0; p < forward.pixelCount(); ++p)
        if (only1.id[p] == 1u && forward.id[p] == 0u) ++overlap;
    EXPECT_GT(overlap, 100u);
    EXPECT_GT(forward.countEntity(1), 0u);
}

// Parallel mode: every sprite uses the camera forward, so two identical models at different
// screen positions trace identical cell images; per-entity mode gives each its own view.
TEST(ViewModes, ParallelModeSharesOneViewPerEntityModeDoesNot) {
    Scene s;
    s.models = {test::markedBar()};
    for (double x : {-1.5, 1.5}) {
        Entity e;
        e.position = {x, 0.0, -4.0};
        s.entities.push_back(e);
    }
    s.camera.position = {0.0, 1.0, 0.0};
    s.camera.target = {0.0, 0.0, -4.0};
    for (ViewMode mode : {ViewMode::Parallel, ViewMode::PerEntity}) {
        s.render.viewMode = mode;
        const auto sprites = setupSprites(s, makeCameraFrame(s.camera), 0.0);
        const CellImage a = traceCells(sprites[0].gpu, s.models[0]->frame(0));
        const CellImage b = traceCells(sprites[1].gpu, s.models[0]->frame(0));
        const bool same = a.range == b.range && a.kind == b.kind && a.face == b.face;
        EXPECT_EQ(same, mode == ViewMode::Parallel);
    }
}

// HARD_CASES 14: identical output with 1 thread and with all threads.
TEST(Determinism, ImageIndependentOfThreadCount) {
    const Scene s = test::hardCaseWorld(glm::dvec3(0.0));
    const Image many = render(s);
    Image one;
    {
        tbb::global_control limit(tbb::global_control::max_allowed_parallelism, 1);
        one = render(s);
    }
    EXPECT_TRUE(diffImages(many, one).identical());
}

} // namespace
} // namespace voxtier
