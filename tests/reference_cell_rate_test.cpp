// Cell-rate sprites in the CPU reference (core/near_rate.hpp, DESIGN.md §3.11): tracing
// each lattice cell once and shading pixels by lookup gives the per-pixel image exactly (colour,
// depth bits, entity id) on the golden scenes, every bundled .vox model from 46 directions at
// sigma 0.5 to 3, rolled and straight-down cameras, cross-fades, sprites partly off-screen or
// crossing the near plane, equal depths, 10^6 m from the origin, and when the cell budget runs
// out part way through a frame.
#include "core/model_view.hpp"
#include "core/scene_loader.hpp"
#include "core/vox_reader.hpp"
#include "test_support.hpp"

#include <gtest/gtest.h>

#include <filesystem>
#include <random>

namespace voxtier {
namespace {

using test::sourcePath;

struct RateImages {
    Image fragment, cell, automatic;
    ReferenceStats fragmentStats, cellStats, autoStats;
    std::uint64_t visible = 0;
    bool cellCompared = true; ///< false: forced cell-rate skipped (see maxCellsPerPixel)
};

/// One frame of `scene` through the reference at the three rates. `fade` > 0 puts every sprite
/// mid cross-fade (alternately on either dither side).
RateImages renderAtRates(const Scene& scene, float fade = 0.0f,
                         std::uint64_t budgetBytes = kDefaultCellBudgetBytes,
                         std::uint64_t maxCellsPerPixel = 1000000) {
    const CameraFrame cam = makeCameraFrame(scene.cameraAt(0.0));
    std::vector<SpriteSetup> sprites = setupSprites(scene, cam, 0.0);
    RateImages r;
    for (std::size_t i = 0; i < sprites.size(); ++i) {
        sprites[i].gpu.fade = fade;
        sprites[i].gpu.fadeSide = i % 2 ? 1.0f : -1.0f;
        r.visible += sprites[i].visible();
    }
    auto render = [&](NearRate rate, ReferenceStats& stats) {
        Image img(cam.width, cam.height, scene.render.background);
        renderReference(scene.models, sprites, img, &stats, {rate, budgetBytes});
        return img;
    };
    r.fragment = render(NearRate::Fragment, r.fragmentStats);
    std::uint64_t cells = 0, pixels = 0;
    for (const SpriteSetup& s : sprites)
        if (s.visible()) cells += cellCount(s), pixels += rectPixels(s);
    // Forced cell-rate on sub-pixel cells (a 256^3 model fitted into a small image) traces up to
    // hundreds of times more rays than pixels: too slow for the suite, and auto never does it.
    r.cell = cells <= maxCellsPerPixel * pixels ? render(NearRate::Cell, r.cellStats) : r.fragment;
    r.cellCompared = cells <= maxCellsPerPixel * pixels;
    r.automatic = render(NearRate::Auto, r.autoStats);
    return r;
}

/// The three images are identical, and each rate did what it says.
void expectRatesAgree(const Scene& scene, const std::string& what, float fade = 0.0f) {
    const RateImages r = renderAtRates(scene, fade);
    EXPECT_EQ(test::describeDifference(r.cell, r.fragment, "cell", "fragment"), "") << what;
    EXPECT_EQ(test::describeDifference(r.automatic, r.fragment, "auto", "fragment"), "") << what;
    EXPECT_EQ(r.fragmentStats.cellSprites, 0u) << what;
    EXPECT_EQ(r.fragmentStats.pixelsLookedUp, 0u) << what;
    EXPECT_EQ(r.cellStats.cellSprites, r.visible) << what;
    EXPECT_EQ(r.cellStats.pixelsTraced, 0u) << what;
    EXPECT_EQ(r.cellStats.pixelsLookedUp, r.fragmentStats.pixelsTraced) << what;
}

TEST(ReferenceCellRate, GoldenAndDefaultScenesAreIdenticalAtEveryRate) {
    for (const char* file :
         {"scenes/golden/arrows.json", "scenes/golden/crowd.json", "scenes/golden/equal_depth.json",
          "scenes/golden/far_origin.json", "scenes/golden/topdown.json", "scenes/default.json"}) {
        const Scene scene = loadScene(sourcePath(file));
        expectRatesAgree(scene, file);
        expectRatesAgree(scene, std::string(file) + " cross-fading", 0.4f);
    }
}

TEST(ReferenceCellRate, HardCasesAreIdenticalAtEveryRate) {
    expectRatesAgree(test::hardCaseWorld(glm::dvec3(0.0)), "hard-case world");
    expectRatesAgree(test::hardCaseWorld(glm::dvec3(1 << 20)), "hard-case world at 10^6 m");
    expectRatesAgree(test::topDownMarkedBar(), "straight down");
    expectRatesAgree(test::equalDepthPair(), "equal-depth pair");
    expectRatesAgree(test::entityBehindCamera(), "behind the camera");
    for (const Scene& s : test::eyeInsideAndOnProxyBox()) expectRatesAgree(s, "eye in proxy box");
    for (int roll = 1; roll < 4; ++roll)
        for (double sigma : {0.5, 1.0, 3.0}) {
            const std::string what =
                "roll " + std::to_string(roll) + " sigma " + std::to_string(sigma);
            test::ViewSetup v =
                test::viewAlong(test::markedBar(), glm::dvec3(2, -1, 3), sigma, 3, roll);
            expectRatesAgree(v.scene, what);
            expectRatesAgree(v.scene, what + " cross-fading", 0.7f);
        }
}

TEST(ReferenceCellRate, PartlyOffScreenAndCrossingTheNearPlane) {
    // Magnified (4 px per cell) with the camera turned so the sprite is cut by the image edge.
    test::ViewSetup v = test::viewAlong(test::solidBox({12, 9, 7}), glm::dvec3(1, 1, 2), 1.0, 4);
    Camera& c = v.scene.camera;
    c.target += glm::dvec3(0.35, 0.2, 0.0);
    const RateImages cut = renderAtRates(v.scene);
    EXPECT_GT(test::drawnPixels(cut.fragment), 100u);
    EXPECT_EQ(test::describeDifference(cut.cell, cut.fragment, "cell", "fragment"), "");
    // The eye between the near plane distance and the model: part of the sprite plane is
    // nearer than 2 zNear (the kernel's denMax), so part of the sprite is clipped.
    for (double d : {0.05, 0.2, 0.4}) {
        Scene s = v.scene;
        const glm::dvec3 toward = glm::normalize(s.camera.position - s.entities[0].position);
        s.camera.position = s.entities[0].position + toward * d;
        s.camera.zNear = 0.3;
        expectRatesAgree(s, "eye at " + std::to_string(d) + " m");
    }
}

// Every model shipped in scenes/vox/ (the list the Vulkan sweep keeps complete) from the 26
// canonical and 20 seeded random directions at sigma 0.5, 1, 2 and 3.
TEST(ReferenceCellRate, EveryVoxModelEveryDirectionEverySigma) {
    const std::vector<glm::dvec3> dirs = test::sweepDirections();
    int frames = 0, cellFrames = 0;
    for (const test::BundledModel& b : test::bundledVoxModels())
        for (double sigma : {0.5, 1.0, 2.0, 3.0})
            for (std::size_t k = 0; k < dirs.size(); ++k) {
                const Scene scene =
                    sceneForModel(b.model, test::viewToward(dirs[k], sigma, 64, 48));
                const RateImages r = renderAtRates(scene, 0.0f, kDefaultCellBudgetBytes, 4);
                ++frames;
                cellFrames += r.cellCompared;
                const std::string where = b.file + " model " + std::to_string(b.index) + " sigma " +
                                          std::to_string(sigma) + " direction #" +
                                          std::to_string(k);
                ASSERT_EQ(test::describeDifference(r.cell, r.fragment, "cell", "fragment"), "")
                    << where;
                ASSERT_EQ(test::describeDifference(r.automatic, r.fragment, "auto", "fragment"), "")
                    << where;
            }
    EXPECT_GT(frames, 12 * 4 * 46);
    EXPECT_GT(cellFrames, frames / 2) << "most frames compare forced cell-rate too";
}

// The rule cell-rate rests on, cell by cell (DESIGN.md §3.11): the outline folded in from the
// neighbours' stored primaries (vtOutcomeFromPrimaries, EMPTY outside cellRange) is vtShadeCell's
// outcome for every cell of the range, because cells just outside the range never hit (checked
// here on a two-cell ring around it). Every bundled model, 46 directions, sigma 0.5 to 3, where
// a sprite has at most 4 cells per pixel (past that auto never draws it cell-rate, and the
// cells of a 256^3 model at sigma 3 would take minutes).
TEST(ReferenceCellRate, OutlineFromNeighbourPrimariesIsVtShadeCell) {
    const std::vector<glm::dvec3> dirs = test::sweepDirections();
    std::uint64_t cells = 0, outlines = 0, ring = 0;
    for (const test::BundledModel& b : test::bundledVoxModels())
        for (double sigma : {0.5, 1.0, 2.0, 3.0})
            for (std::size_t k = 0; k < dirs.size(); ++k) {
                const Scene scene =
                    sceneForModel(b.model, test::viewToward(dirs[k], sigma, 64, 48));
                const CameraFrame cam = makeCameraFrame(scene.cameraAt(0.0));
                const SpriteSetup sprite = setupSprites(scene, cam, 0.0)[0];
                if (!sprite.visible() || cellCount(sprite) > 4 * rectPixels(sprite)) continue;
                const kernel::SpriteGpu& g = sprite.gpu;
                struct Voxels {
                    const VoxelGrid& grid;
                    kernel::uint fetch(glm::ivec3 c) const { return grid.at(c); }
                } voxels{b.model->frame(0)};
                kernel::SpriteTracer<Voxels> tracer{voxels};
                const std::string where = b.file + " model " + std::to_string(b.index) + " sigma " +
                                          std::to_string(sigma) + " direction #" +
                                          std::to_string(k);
                // Primaries of the range and the ring: the ring must miss.
                const glm::ivec4 r = g.cellRange;
                const int w = r.y - r.x + 5;
                std::vector<kernel::uint> primaries(std::size_t(w) * std::size_t(r.w - r.z + 5));
                const auto slot = [&](glm::ivec2 c) {
                    return std::size_t(c.y - r.z + 2) * std::size_t(w) + std::size_t(c.x - r.x + 2);
                };
                for (int j = r.z - 2; j <= r.w + 2; ++j)
                    for (int i = r.x - 2; i <= r.y + 2; ++i) {
                        const kernel::uint p = tracer.vtTraceCellPrimary(g, {i, j});
                        primaries[slot({i, j})] = p;
                        if (kernel::vtCellInRange(g, {i, j})) continue;
                        ++ring;
                        ASSERT_EQ(p, kernel::VT_KIND_EMPTY)
                            << where << ": cell " << i << "," << j << " outside the range hits";
                    }
                const auto primary = [&](glm::ivec2 c) {
                    return kernel::vtCellInRange(g, c) ? primaries[slot(c)] : kernel::VT_KIND_EMPTY;
                };
                const CellImage shaded = traceCells(g, b.model->frame(0));
                for (int j = r.z; j <= r.w; ++j)
                    for (int i = r.x; i <= r.y; ++i) {
                        const glm::ivec2 c(i, j);
                        const std::size_t at = shaded.at(i, j);
                        ASSERT_EQ(kernel::vtOutcomeFromPrimaries(
                                      primary(c), primary(c + glm::ivec2(-1, 0)),
                                      primary(c + glm::ivec2(1, 0)), primary(c + glm::ivec2(0, -1)),
                                      primary(c + glm::ivec2(0, 1))),
                                  kernel::vtPackOutcome(shaded.kind[at], shaded.index[at],
                                                        shaded.face[at]))
                            << where << ": cell " << i << "," << j;
                        ++cells;
                        outlines += shaded.kind[at] == kernel::VT_KIND_OUTLINE;
                    }
            }
    EXPECT_GT(cells, 100000u);
    EXPECT_GT(outlines, cells / 50) << "the sweep exercises outlines";
    EXPECT_GT(ring, 0u);
}

// A budget smaller than the frame's cells: the sprites that do not fit are traced per pixel,
// counted, and the image does not change.
TEST(ReferenceCellRate, SpritesPastTheCellBudgetFallBackToPerPixel) {
    const Scene scene = test::hardCaseWorld(glm::dvec3(0.0));
    const RateImages all = renderAtRates(scene);
    ASSERT_EQ(all.cellStats.cellSprites, 4u);
    // Room for the first sprite's cells and not for all of them.
    const CameraFrame cam = makeCameraFrame(scene.cameraAt(0.0));
    const std::vector<SpriteSetup> sprites = setupSprites(scene, cam, 0.0);
    const std::uint64_t firstCells = cellCount(sprites[0]);
    const RateImages tight = renderAtRates(scene, 0.0f, firstCells * kCellStoreBytesPerCell);
    EXPECT_GE(tight.cellStats.cellSprites, 1u);
    EXPECT_LT(tight.cellStats.cellSprites, 4u);
    EXPECT_EQ(tight.cellStats.cellSprites + tight.cellStats.cellOverBudget, 4u);
    EXPECT_LE(tight.cellStats.cellsTraced, firstCells);
    EXPECT_GT(tight.cellStats.pixelsTraced, 0u);
    EXPECT_EQ(test::describeDifference(tight.cell, all.fragment, "cell", "fragment"), "");
    const RateImages none = renderAtRates(scene, 0.0f, 0);
    EXPECT_EQ(none.cellStats.cellSprites, 0u);
    EXPECT_EQ(none.cellStats.cellOverBudget, 4u);
    EXPECT_EQ(test::describeDifference(none.cell, all.fragment, "cell", "fragment"), "");
}

// The auto rule at its crossover: cell-rate exactly when kCellRateCost * C < P.
TEST(ReferenceCellRate, AutoCrossoverIsStrict) {
    SpriteSetup s;
    s.gpu.cellRange = {-5, 4, -3, 2}; // 10 x 6 cells
    const std::uint64_t cells = cellCount(s);
    ASSERT_EQ(cells, 60u);
    const int crossover = int(kCellRateCost * double(cells)); // the rectangle's pixels there
    for (int extra : {-1, 0, 1}) {
        s.screenRect = {10, 20, 10 + crossover + extra, 21}; // one row of pixels
        const SpriteSetup* one[] = {&s};
        const CellRatePlan plan = planCellRate(one, NearRate::Auto);
        EXPECT_EQ(plan.cellSprites, extra > 0 ? 1u : 0u) << extra;
        EXPECT_EQ(plan.cells, extra > 0 ? cells : 0u) << extra;
    }
}

// The Vulkan splat orders cell-rate sprites by a depth rank in 19 bits of a pixel word: past
// maxCellSprites (kMaxCellSprites by default) a frame's sprites are traced per pixel, in order,
// and counted as over budget.
TEST(ReferenceCellRate, SpritesPastTheSpriteCapFallBackToPerPixel) {
    EXPECT_EQ(kMaxCellSprites, std::uint64_t(1) << 19);
    std::vector<SpriteSetup> sprites(3);
    for (std::size_t k = 0; k < sprites.size(); ++k) {
        sprites[k].gpu.cellRange = {0, 9, 0, 9}; // 100 cells
        sprites[k].screenRect = {0, 0, 50 + int(k), 40};
    }
    const SpriteSetup* all[] = {&sprites[0], &sprites[1], &sprites[2]};
    const CellRatePlan capped = planCellRate(all, NearRate::Cell, kDefaultCellBudgetBytes, 2);
    EXPECT_EQ(capped.cellSprites, 2u);
    EXPECT_EQ(capped.overBudget, 1u);
    EXPECT_EQ(capped.cells, 200u);
    EXPECT_EQ(capped.cellBase, (std::vector<std::uint32_t>{0, 100, kNoCells}));
    EXPECT_EQ(capped.pixelsTraced, rectPixels(sprites[2]));
    EXPECT_EQ(capped.pixelsLookedUp, rectPixels(sprites[0]) + rectPixels(sprites[1]));
    const CellRatePlan uncapped = planCellRate(all, NearRate::Cell);
    EXPECT_EQ(uncapped.cellSprites, 3u);
    EXPECT_EQ(uncapped.overBudget, 0u);
}

// Near the crossover (one screen pixel per cell: P ~ C) and on a 256^3 model: identical.
TEST(ReferenceCellRate, AtTheCrossoverAndOnA256CubedModel) {
    const auto bar = test::markedBar();
    for (double sigma : {0.9, 1.0, 1.1})
        expectRatesAgree(test::viewAlong(bar, glm::dvec3(1, -2, 3), sigma, 1).scene,
                         "crossover sigma " + std::to_string(sigma));
    const auto big = test::solidBox({256, 256, 256}, 3);
    const Scene bigScene = test::viewAlong(big, glm::dvec3(1, 2, 3), 0.5, 2).scene;
    expectRatesAgree(bigScene, "256^3, sigma 0.5");
    const RateImages r = renderAtRates(bigScene);
    EXPECT_GT(test::drawnPixels(r.cell), 50000u);
    EXPECT_GT(r.cellStats.cellsTraced, 10000u);
}

// Auto picks cell-rate for a magnified sprite and per-pixel for a minified one.
TEST(ReferenceCellRate, AutoChoosesByCellsAgainstPixels) {
    const auto model = test::solidBox({16, 12, 8});
    const RateImages close =
        renderAtRates(test::viewAlong(model, glm::dvec3(1, 2, 3), 1.0, 4).scene);
    EXPECT_EQ(close.autoStats.cellSprites, 1u);
    // A third of a pixel per cell: nine cells per pixel.
    test::ViewSetup far = test::viewAlong(model, glm::dvec3(1, 2, 3), 1.0, 1);
    Scene& sc = far.scene;
    sc.camera.position =
        sc.entities[0].position + (sc.camera.position - sc.entities[0].position) * 3.0;
    const RateImages small = renderAtRates(sc);
    EXPECT_EQ(small.autoStats.cellSprites, 0u);
    EXPECT_GT(small.autoStats.pixelsTraced, 0u);
}

} // namespace
} // namespace voxtier
