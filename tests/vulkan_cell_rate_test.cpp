// Cell-rate sprites on Vulkan (core/near_rate.hpp, CONTRACT.md §3.11): compute passes trace
// every cell of the frame's cell-rate sprites (primary rays, then the outline from the
// neighbours), splat their pixels' depth ranks, and after the draw of the per-pixel sprites
// shade the pixels they won. The image equals the per-pixel Vulkan image and the CPU reference
// pixel for pixel (colour, depth bits, id), and the validation layer (synchronization
// validation included) stays silent.
#include "core/model_view.hpp"
#include "core/running_totals.hpp"
#include "core/scene_loader.hpp"
#include "core/vox_reader.hpp"
#include "hard_case_scenes.hpp"
#include "image_checks.hpp"
#include "source_tree.hpp"
#include "test_models.hpp"
#include "view_sweeps.hpp"
#include "vulkan_test_env.hpp"

#include <gtest/gtest.h>
#include <tbb/task_arena.h>

#include <cstdlib>
#include <filesystem>

namespace voxtier {
namespace {

const auto* const kEnv = ::testing::AddGlobalTestEnvironment(new test::NearRendererEnvironment);

using test::sourcePath;

class VulkanCellRate : public test::VulkanTest {
  protected:
    /// The scene's camera at `eye`, looking down -z, `width` x `height` pixels: its frame at t 0.
    static CameraFrame lookDownMinusZ(Scene& scene, glm::dvec3 eye, int width, int height) {
        scene.camera.position = eye;
        scene.camera.target = {0.0, 0.0, -10.0};
        scene.camera.width = width;
        scene.camera.height = height;
        return makeCameraFrame(scene.cameraAt(0.0));
    }
    /// Vulkan at `rate` equals the reference, its per-pixel sprites traced in compute (a GPU's
    /// default) and rasterised (their pixels then composed with the cell-rate ones by the
    /// resolve against the drawn depth); returns the near stats of the first.
    NearStats expectMatchesReference(const Scene& scene, NearRate rate, const std::string& what,
                                     std::uint64_t budgetBytes = kDefaultCellBudgetBytes) {
        NearOptions options = test::gpuDefaults();
        options.rate = rate;
        options.cellBudgetBytes = budgetBytes;
        const auto r = test::renderBoth(nearRenderer(), scene, 0.0, options);
        EXPECT_EQ(test::describeDifference(r.near, r.reference), "") << what << ", compute";
        options.pixels = NearPixels::Raster;
        const Image drawn =
            nearRenderer().render(makeCameraFrame(scene.cameraAt(0.0)), scene.models, r.sprites,
                                  scene.render.background, options);
        EXPECT_EQ(test::describeDifference(drawn, r.reference), "") << what << ", raster";
        // The records in the order the sprites are given (NearRecords::Given), given back to
        // front: each place in the draw order finds its record through its own index.
        options.pixels = NearPixels::Compute;
        options.records = NearRecords::Given;
        const std::vector<SpriteSetup> reversed(r.sprites.rbegin(), r.sprites.rend());
        const Image given =
            nearRenderer().render(makeCameraFrame(scene.cameraAt(0.0)), scene.models, reversed,
                                  scene.render.background, options);
        EXPECT_EQ(test::describeDifference(given, r.reference), "")
            << what << ", compute, records in the order given (reversed)";
        return r.nearStats;
    }
    /// Cell, fragment and auto all equal the reference; cell really drew every sprite cell-rate.
    void expectEveryRateMatches(const Scene& scene, const std::string& what) {
        const NearStats cell = expectMatchesReference(scene, NearRate::Cell, what + " (cell)");
        EXPECT_EQ(cell.cellSprites, cell.sprites) << what;
        EXPECT_EQ(cell.pixelsTraced, 0u) << what;
        const NearStats fragment =
            expectMatchesReference(scene, NearRate::Fragment, what + " (fragment)");
        EXPECT_EQ(fragment.cellSprites, 0u) << what;
        EXPECT_EQ(fragment.cellsTraced, 0u) << what;
        expectMatchesReference(scene, NearRate::Auto, what + " (auto)");
    }
};

TEST_F(VulkanCellRate, GoldenScenesMatchTheReferenceAtEveryRate) {
    for (const char* file :
         {"scenes/golden/arrows.json", "scenes/golden/crowd.json", "scenes/golden/equal_depth.json",
          "scenes/golden/far_origin.json", "scenes/golden/topdown.json", "scenes/default.json"})
        expectEveryRateMatches(loadScene(sourcePath(file)), file);
}

TEST_F(VulkanCellRate, HardCasesMatchTheReferenceAtEveryRate) {
    expectEveryRateMatches(test::hardCaseWorld(glm::dvec3(0.0)), "hard-case world");
    expectEveryRateMatches(test::hardCaseWorld(glm::dvec3(1 << 20)), "hard-case world at 10^6 m");
    expectEveryRateMatches(test::topDownMarkedBar(), "straight down");
    expectEveryRateMatches(test::equalDepthPair(), "equal-depth pair");
    for (const Scene& s : test::eyeInsideAndOnProxyBox()) expectEveryRateMatches(s, "eye in box");
    for (int roll = 1; roll < 4; ++roll)
        for (double sigma : {0.5, 3.0})
            expectEveryRateMatches(
                test::viewAlong(test::markedBar(), glm::dvec3(2, -1, 3), sigma, 3, roll).scene,
                "roll " + std::to_string(roll) + " sigma " + std::to_string(sigma));
    // Magnified, cut by the image edge, and with the eye close enough that part of the sprite
    // plane is nearer than 2 zNear.
    test::ViewSetup v = test::viewAlong(test::solidBox({12, 9, 7}), glm::dvec3(1, 1, 2), 1.0, 4);
    v.scene.camera.target += glm::dvec3(0.35, 0.2, 0.0);
    expectEveryRateMatches(v.scene, "partly off-screen");
    const glm::dvec3 toward =
        glm::normalize(v.scene.camera.position - v.scene.entities[0].position);
    v.scene.camera.position = v.scene.entities[0].position + toward * 0.2;
    v.scene.camera.zNear = 0.3;
    expectEveryRateMatches(v.scene, "crossing the near plane");
}

// Sprites whose proxy quad crosses the near plane: the screen rectangle (which the reference,
// the rate rule and the cell-rate passes walk) is the quad clipped at zNear. It used to be the
// whole image: frame 107 of the RTS top-down bench path summed 39.7 million rectangle pixels
// over a 960x540 image, and cell-rate made that frame slower than per pixel. The clipped
// rectangles lose nothing: the reference drawing those sprites over the whole image (as before)
// gives the same image, and Vulkan equals the reference.
TEST_F(VulkanCellRate, QuadsCrossingTheNearPlaneGetClippedRectangles) {
    const Scene scene = loadScene(sourcePath("scenes/bench/rts_topdown.json"));
    const double time = scene.timeOfFrame(107);
    const CameraFrame cam = makeCameraFrame(scene.cameraAt(time));
    const std::vector<SpriteSetup> sprites = setupSprites(scene, cam, time);
    std::vector<SpriteSetup> whole = sprites;
    std::uint64_t rects = 0;
    int crossing = 0;
    for (std::size_t i = 0; i < sprites.size(); ++i) {
        if (sprites[i].visible()) rects += rectPixels(sprites[i]);
        bool behind = false;
        for (const glm::vec4& q : sprites[i].quad) behind |= !(double(q.w) > cam.zNear);
        if (!behind || !(sprites[i].visible() || sprites[i].cull == CullReason::OffScreen))
            continue;
        ++crossing;
        whole[i].screenRect = {0, 0, cam.width, cam.height};
        whole[i].cull = CullReason::None;
    }
    EXPECT_GT(crossing, 5);
    EXPECT_LT(rects, 4 * std::uint64_t(cam.width) * std::uint64_t(cam.height));
    Image clipped(cam.width, cam.height, scene.render.background);
    renderReference(scene.models, sprites, clipped);
    Image unclipped(cam.width, cam.height, scene.render.background);
    renderReference(scene.models, whole, unclipped);
    EXPECT_EQ(test::describeDifference(clipped, unclipped, "clipped", "whole image"), "");
    for (NearRate rate : {NearRate::Fragment, NearRate::Auto}) {
        NearOptions options = test::gpuDefaults();
        options.rate = rate;
        const Image near =
            nearRenderer().render(cam, scene.models, sprites, scene.render.background, options);
        EXPECT_EQ(test::describeDifference(near, clipped), "");
    }
}

// Near the auto crossover (one screen pixel per cell: P ~ C) and on a 256^3 model.
TEST_F(VulkanCellRate, AtTheCrossoverAndOnA256CubedModel) {
    const auto bar = test::markedBar();
    for (double sigma : {0.9, 1.0, 1.1})
        expectEveryRateMatches(test::viewAlong(bar, glm::dvec3(1, -2, 3), sigma, 1).scene,
                               "crossover sigma " + std::to_string(sigma));
    expectEveryRateMatches(
        test::viewAlong(test::solidBox({256, 256, 256}, 3), glm::dvec3(1, 2, 3), 0.5, 2).scene,
        "256^3, sigma 0.5");
}

// Every bundled .vox model, 26 canonical and 20 seeded random directions, sigma 0.5 to 3, forced
// cell-rate (the
// per-pixel and auto paths are swept by vulkan_identity_test). Frames whose cells outnumber
// their pixels more than 4 : 1 are left to the CPU test (auto never draws them cell-rate).
TEST_F(VulkanCellRate, EveryVoxModelEveryDirectionAtCellRate) {
    const std::vector<glm::dvec3> dirs = test::sweepDirections();
    int frames = 0;
    for (const test::BundledModel& b : test::bundledVoxModels())
        for (double sigma : {0.5, 1.0, 2.0, 3.0})
            for (const glm::dvec3& d : dirs) {
                const Scene scene = sceneForModel(b.model, test::viewToward(d, sigma, 64, 48));
                const CameraFrame cam = makeCameraFrame(scene.cameraAt(0.0));
                const auto sprites = setupSprites(scene, cam, 0.0);
                if (!sprites[0].visible() || cellCount(sprites[0]) > 4 * rectPixels(sprites[0]))
                    continue;
                ++frames;
                const NearStats st =
                    expectMatchesReference(scene, NearRate::Cell,
                                           b.file + " model " + std::to_string(b.index) +
                                               " sigma " + std::to_string(sigma));
                ASSERT_EQ(st.cellSprites, 1u);
                if (HasFailure()) return;
            }
    EXPECT_GT(frames, 12 * 46);
}

// A cell budget smaller than the frame needs: the rest is drawn per pixel, counted, same image.
TEST_F(VulkanCellRate, SpritesPastTheCellBudgetFallBackToPerPixel) {
    const Scene scene = test::hardCaseWorld(glm::dvec3(0.0));
    const CameraFrame cam = makeCameraFrame(scene.cameraAt(0.0));
    const auto sprites = setupSprites(scene, cam, 0.0);
    const std::uint64_t firstBytes = cellCount(sprites[0]) * kCellStoreBytesPerCell;
    const NearStats tight =
        expectMatchesReference(scene, NearRate::Cell, "tight budget", firstBytes);
    EXPECT_GE(tight.cellSprites, 1u);
    EXPECT_GE(tight.cellOverBudget, 1u);
    EXPECT_EQ(tight.cellSprites + tight.cellOverBudget, tight.sprites);
    EXPECT_LE(tight.cellsTraced * kCellStoreBytesPerCell, firstBytes);
    const NearStats none = expectMatchesReference(scene, NearRate::Cell, "no budget", 0);
    EXPECT_EQ(none.cellSprites, 0u);
    EXPECT_EQ(none.cellOverBudget, none.sprites);
}

// Equal depth across the two paths: a cell-rate sprite (splat + resolve) and a per-pixel one
// (drawn) overlapping at the same depth, the lower entity id on either path. The cell budget
// picks which one is cell-rate: the plan goes in entity order and skips what does not fit.
TEST_F(VulkanCellRate, EqualDepthTiesBetweenCellRateAndPerPixelSprites) {
    for (bool smallFirst : {true, false}) {
        Scene scene = test::equalDepthPair();
        scene.models[smallFirst ? 1 : 0] = test::solidBox({9, 9, 9}, 7);
        const CameraFrame cam = makeCameraFrame(scene.cameraAt(0.0));
        const auto sprites = setupSprites(scene, cam, 0.0);
        ASSERT_EQ(sprites[0].gpu.depth, sprites[1].gpu.depth);
        const std::size_t small = smallFirst ? 0 : 1;
        const std::uint64_t budget = cellCount(sprites[small]) * kCellStoreBytesPerCell;
        const std::string what = smallFirst ? "cell-rate sprite first" : "per-pixel sprite first";
        const NearStats st = expectMatchesReference(scene, NearRate::Cell, what, budget);
        EXPECT_EQ(st.cellSprites, 1u) << what;
        EXPECT_EQ(st.cellOverBudget, 1u) << what;
        // Both sprites show: the tie really was decided between the two paths.
        const auto r = test::renderBoth(nearRenderer(), scene);
        EXPECT_GT(r.near.countEntity(sprites[0].entityId), 0u);
        EXPECT_GT(r.near.countEntity(sprites[1].entityId), 0u);
    }
}

// Sprites mid cross-fade (both dither sides) drawn cell-rate: the splat applies the dither.
TEST_F(VulkanCellRate, CrossFadingSpritesAtCellRate) {
    for (const char* file : {"scenes/golden/crowd.json", "scenes/golden/equal_depth.json"}) {
        const Scene scene = loadScene(sourcePath(file));
        const CameraFrame cam = makeCameraFrame(scene.cameraAt(0.0));
        std::vector<SpriteSetup> sprites = setupSprites(scene, cam, 0.0);
        for (std::size_t i = 0; i < sprites.size(); ++i) {
            sprites[i].gpu.fade = 0.375f;
            sprites[i].gpu.fadeSide = i % 2 ? 1.0f : -1.0f;
        }
        Image reference(cam.width, cam.height, scene.render.background);
        renderReference(scene.models, sprites, reference);
        for (NearRate rate : {NearRate::Cell, NearRate::Auto}) {
            NearOptions options = test::gpuDefaults();
            options.rate = rate;
            NearStats st;
            const Image near = nearRenderer().render(cam, scene.models, sprites,
                                                     scene.render.background, options, &st);
            EXPECT_EQ(test::describeDifference(near, reference), "") << file;
            if (rate == NearRate::Cell) {
                EXPECT_EQ(st.cellSprites, st.sprites) << file;
            }
        }
    }
}

// The scale the budget exists for: a sigma 16 crowd of 256^3 models (about 50 million cells
// each, 400 MB of cell store) among small 16^3 ones, forced cell-rate under the default 64 MiB
// budget. Small sprites fit until the store is full (each needs 1.5 MB), every 256^3 one falls
// back to per pixel and is counted, the store stays under the budget, and the image is the
// reference's.
TEST_F(VulkanCellRate, Sigma16CrowdOf256CubedModelsFallsBackPastTheDefaultBudget) {
    Scene scene;
    scene.render.sigma = 16.0;
    scene.render.voxelSize = 0.01;
    scene.models = {test::solidBox({256, 256, 256}, 3), test::solidBox({16, 16, 16}, 1)};
    for (int k = 0; k < 400; ++k) {
        Entity e;
        e.model = k % 4 == 0 ? 0 : 1; // 100 big, 300 small
        e.position = {double(k % 20) * 0.6 - 6.0, double(k / 20 % 5) * 0.5 - 1.0,
                      -4.0 - double(k / 100) * 6.0};
        scene.entities.push_back(e);
    }
    const CameraFrame cam = lookDownMinusZ(scene, {0.0, 0.0, 2.0}, 160, 96);
    const auto sprites = setupSprites(scene, cam, 0.0);
    std::uint64_t bigVisible = 0;
    for (const SpriteSetup& sp : sprites)
        if (sp.visible() && sp.model == 0) {
            ++bigVisible;
            ASSERT_GT(cellCount(sp) * kCellStoreBytesPerCell, kDefaultCellBudgetBytes);
        }
    ASSERT_GT(bigVisible, 10u);
    const NearStats st = expectMatchesReference(scene, NearRate::Cell, "sigma 16, 256^3 crowd");
    EXPECT_GE(st.cellOverBudget, bigVisible);
    EXPECT_GT(st.cellSprites, 10u);
    EXPECT_EQ(st.cellSprites + st.cellOverBudget, st.sprites);
    EXPECT_LE(st.cellsTraced * kCellStoreBytesPerCell, kDefaultCellBudgetBytes);
    EXPECT_GT(st.pixelsTraced, 0u);
}

// A crowd of 12,288 small sprites over the same pixels, in three blocks each front to back in
// itself: in entity order (no early depth test) the host's ranking must sort them across the
// blocks' seams (the least rank in a pixel is the nearest sprite); front to back it needs no sort.
// Per pixel and at cell rate with the cell budget ample and running out part way (the rate plan's
// fallback to per pixel), traced in compute and rasterised, the lists built on one thread and in
// chunks on eight (core/running_totals.hpp: each block is a chunk, so only the seams between
// chunks are out of order): the reference's image each time. Then the blocks one behind the
// other, each shuffled in itself: out of order within the chunks, in order at their seams.
TEST_F(VulkanCellRate, ACrowdOfTwelveThousandSpritesMatchesTheReferenceInEitherOrder) {
    for (const bool shuffled : {false, true}) {
        Scene scene;
        scene.render.voxelSize = 0.05;
        scene.models = {test::solidBox({4, 4, 4}, 1), test::solidBox({4, 3, 4}, 2)};
        constexpr int kBlock = int(kRunningTotalsChunk), kBlocks = 3;
        for (int b = 0; b < kBlocks; ++b)
            for (int j = 0; j < kBlock; ++j) {
                Entity e;
                e.model = (j + b) % 2;
                e.position = {double((j * 37) % 64) / 64.0 * 4.0 - 2.0 + 0.02 * b,
                              double((j * 11) % 48) / 48.0 * 2.4 - 1.2,
                              shuffled ? -3.0 - 1.5 * b - 0.0003 * ((j * 7) % kBlock)
                                       : -3.0 - 0.001 * j};
                scene.entities.push_back(e);
            }
        const CameraFrame cam = lookDownMinusZ(scene, {0.0, 0.0, 0.0}, 192, 108);
        const std::vector<SpriteSetup> sprites = setupSprites(scene, cam, 0.0);
        std::size_t visible = 0;
        for (const SpriteSetup& sp : sprites) visible += sp.visible();
        ASSERT_EQ(visible, sprites.size()) << "every sprite drawn";
        Image reference(cam.width, cam.height, scene.render.background);
        renderReference(scene.models, sprites, reference);
        std::uint64_t cells = 0;
        for (const SpriteSetup& sp : sprites) cells += cellCount(sp);
        for (const bool earlyDepth : {true, false})
            for (const NearRate rate : {NearRate::Fragment, NearRate::Cell})
                for (const std::uint64_t budget :
                     {kDefaultCellBudgetBytes, cells / 2 * kCellStoreBytesPerCell}) {
                    if (rate == NearRate::Fragment && budget != kDefaultCellBudgetBytes) continue;
                    for (const NearPixels pixels : {NearPixels::Compute, NearPixels::Raster})
                        for (const int threads : {1, 8, -8}) {
                            // -8: eight threads, the records in the order given (NearRecords).
                            NearOptions options = test::gpuDefaults();
                            if (threads < 0) options.records = NearRecords::Given;
                            options.earlyDepthTest = earlyDepth;
                            options.rate = rate;
                            options.cellBudgetBytes = budget;
                            options.pixels = pixels;
                            NearStats st;
                            Image drawn;
                            tbb::task_arena(std::abs(threads)).execute([&] {
                                drawn =
                                    nearRenderer().render(cam, scene.models, sprites,
                                                          scene.render.background, options, &st);
                            });
                            const std::string what =
                                std::string(shuffled ? "shuffled blocks, " : "sorted blocks, ") +
                                (earlyDepth ? "front to back" : "entity order") + ", " +
                                (rate == NearRate::Cell ? "cell rate" : "per pixel") + ", budget " +
                                std::to_string(budget) + ", " +
                                (pixels == NearPixels::Compute ? "compute" : "raster") + ", " +
                                std::to_string(std::abs(threads)) + " threads" +
                                (threads < 0 ? ", records in the order given" : "");
                            EXPECT_EQ(test::describeDifference(drawn, reference), "") << what;
                            if (rate == NearRate::Cell) {
                                EXPECT_EQ(st.cellOverBudget > 0, budget != kDefaultCellBudgetBytes)
                                    << what;
                            }
                        }
                }
    }
}

// Frames of different cell counts one after another reuse and grow the one cell store.
TEST_F(VulkanCellRate, ConsecutiveFramesOfGrowingCellCountsStayIdentical) {
    for (int magnification : {1, 2, 6, 3})
        expectMatchesReference(
            test::viewAlong(test::solidBox({20, 14, 9}), glm::dvec3(3, 1, 2), 1.0, magnification)
                .scene,
            NearRate::Cell, "magnification " + std::to_string(magnification));
}

} // namespace
} // namespace voxtier
