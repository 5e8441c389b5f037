// Empty-space skipping on Vulkan (near.frag per pixel, near_cells.comp cell-rate, reading the
// brick occupancy that volumetric/voxel_residency uploads): every sprite forced to march over its
// occupancy draws exactly the CPU reference's cell-by-cell image (colour, depth bits, entity id),
// on every bundled model at both rates, after edits that empty and fill bricks, and the counting
// variant counts exactly the reference's reads (voxel and brick) when skipping.
#include "core/model_view.hpp"
#include "core/procedural.hpp"
#include "test_support.hpp"

#include <gtest/gtest.h>

namespace voxtier {
namespace {

const auto* const kEnv = ::testing::AddGlobalTestEnvironment(new test::NearRendererEnvironment);

class VulkanBrickSkip : public test::VulkanTest {
  protected:
    /// The scene's sprites at t = 0, each forced to skip (or left as setupSprites set them).
    static std::vector<SpriteSetup> sprites(const Scene& scene, bool forceSkip) {
        const CameraFrame cam = makeCameraFrame(scene.cameraAt(0.0));
        std::vector<SpriteSetup> out = setupSprites(scene, cam, 0.0);
        if (forceSkip)
            for (SpriteSetup& s : out) s.gpu.skipEmpty = 1u;
        return out;
    }
    /// The CPU reference's cell-by-cell image of `scene` (no occupancy read).
    static Image cellByCell(const Scene& scene) {
        const CameraFrame cam = makeCameraFrame(scene.cameraAt(0.0));
        Image img(cam.width, cam.height, scene.render.background);
        ReferenceOptions options;
        options.skipEmptyBricks = false;
        renderReference(scene.models, sprites(scene, false), img, nullptr, options);
        return img;
    }
    /// Vulkan, every sprite skipping, at `rate`.
    Image skipping(const Scene& scene, NearRate rate, NearStats* stats = nullptr) {
        NearOptions options = test::gpuDefaults();
        options.rate = rate;
        options.skipEmpty = true; // the pipelines that hold the box march
        return nearRenderer().render(makeCameraFrame(scene.cameraAt(0.0)), scene.models,
                                     sprites(scene, true), scene.render.background, options, stats);
    }
};

// Every bundled model from the 26 canonical and 20 seeded random directions, per pixel and
// cell-rate. Cell-rate where a sprite has at most 4 cells per pixel (as the cell-rate sweep); the
// 256^3 models get their own cell-rate frames at sigma 0.5 in a larger image.
TEST_F(VulkanBrickSkip, EveryBundledModelAtBothRatesEqualsTheCellByCellReference) {
    const std::vector<glm::dvec3> dirs = test::sweepDirections();
    int frames = 0, cellFrames = 0;
    for (const test::BundledModel& b : test::bundledVoxModels()) {
        const glm::ivec3 dims = b.model->frame(0).dims();
        const bool large = std::max({dims.x, dims.y, dims.z}) > 128;
        for (std::size_t k = 0; k < dirs.size(); ++k) {
            const std::string where =
                b.file + " model " + std::to_string(b.index) + " direction #" + std::to_string(k);
            const Scene scene = sceneForModel(b.model, test::viewToward(dirs[k], 1.0, 64, 48));
            const Image want = cellByCell(scene);
            ASSERT_EQ(test::describeDifference(skipping(scene, NearRate::Fragment), want), "")
                << where << " per pixel";
            ++frames;
            const Scene cellScene =
                large ? sceneForModel(b.model, test::viewToward(dirs[k], 0.5, 320, 240)) : scene;
            const SpriteSetup s = sprites(cellScene, true)[0];
            if (!s.visible() || cellCount(s) > 4 * rectPixels(s) || (large && k >= 26)) continue;
            NearStats st;
            const Image cell = skipping(cellScene, NearRate::Cell, &st);
            ASSERT_EQ(test::describeDifference(cell, large ? cellByCell(cellScene) : want), "")
                << where << " cell-rate";
            ASSERT_EQ(st.cellSprites, 1u) << where;
            ++cellFrames;
        }
    }
    EXPECT_GT(frames, 12 * 46);
    EXPECT_GT(cellFrames, frames / 2);
}

// Edits between frames: bricks emptied (a clear) and filled (a fill, a single voxel) reach the
// device with the atlas, and the next frame skips by the new occupancy, at both rates.
TEST_F(VulkanBrickSkip, EditsReachTheDeviceOccupancy) {
    auto tank = makeTank(3, 1, {64, 64, 32});
    const Scene scene = sceneForModel(tank, test::viewToward({1.0, -0.6, 0.8}, 1.0, 160, 120));
    const std::vector<Box3i> clears = {{{0, 0, 0}, {64, 40, 32}}, {{10, 10, 0}, {50, 60, 20}}};
    const std::vector<Box3i> fills = {{{20, 20, 10}, {24, 22, 14}}, {{0, 50, 25}, {5, 64, 32}}};
    for (std::size_t i = 0; i < clears.size(); ++i) {
        for (NearRate rate : {NearRate::Fragment, NearRate::Cell})
            ASSERT_EQ(test::describeDifference(skipping(scene, rate), cellByCell(scene)), "")
                << "before edit " << i;
        tank->clearBox(0, clears[i]);
        for (NearRate rate : {NearRate::Fragment, NearRate::Cell})
            ASSERT_EQ(test::describeDifference(skipping(scene, rate), cellByCell(scene)), "")
                << "after clear " << i;
        tank->fillBox(0, fills[i], 40);
        tank->setVoxel(0, {63, 0, 31}, 41);
    }
    const Image last = skipping(scene, NearRate::Fragment);
    EXPECT_EQ(test::describeDifference(last, cellByCell(scene)), "") << "after the last fill";
    EXPECT_GT(test::drawnPixels(last), 100u);
}

// The counting shader counts a brick read as a voxel read, as the reference does: equal totals
// on a sparse 256^3 model and the bench street, every sprite skipping, every pixel traced.
TEST_F(VulkanBrickSkip, CountingVariantCountsTheReferenceReads) {
    const auto trees = test::bundledVoxModels();
    const auto tree = std::find_if(trees.begin(), trees.end(), [](const test::BundledModel& b) {
        return b.model->frame(0).dims() == glm::ivec3(256);
    });
    ASSERT_NE(tree, trees.end());
    for (const Scene& scene :
         {sceneForModel(tree->model, test::viewToward({1, 2, 3}, 0.5, 200, 150)),
          sceneForModel(test::solidBox({40, 30, 20}), test::viewToward({2, 1, 1}, 1.0, 96, 72))}) {
        NearOptions counting = test::gpuDefaults();
        counting.countSteps = true;
        counting.rate = NearRate::Fragment;
        counting.skipEmpty = true;
        NearStats near;
        const CameraFrame cam = makeCameraFrame(scene.cameraAt(0.0));
        const std::vector<SpriteSetup> all = sprites(scene, true);
        const Image img =
            nearRenderer().render(cam, scene.models, all, scene.render.background, counting, &near);
        Image ref(cam.width, cam.height, scene.render.background);
        ReferenceOptions everyPixel;
        everyPixel.earlyDepthTest = false;
        ReferenceStats rs;
        renderReference(scene.models, all, ref, &rs, everyPixel);
        EXPECT_EQ(test::describeDifference(img, ref), "");
        EXPECT_EQ(near.voxelFetches, rs.voxelFetches);
        EXPECT_GT(rs.brickFetches, 0u);
    }
}

// Without NearOptions::skipEmpty (the default) the pipelines hold no box march: sprites marked to
// skip are traced cell by cell, reading what the cell-by-cell reference reads, and draw its image.
TEST_F(VulkanBrickSkip, WithoutTheOptionEverySpriteIsTracedCellByCell) {
    const Scene scene =
        sceneForModel(test::solidBox({40, 30, 20}), test::viewToward({2, 1, 1}, 1.0, 96, 72));
    NearOptions counting = test::gpuDefaults();
    counting.countSteps = true;
    counting.rate = NearRate::Fragment;
    NearStats near;
    const CameraFrame cam = makeCameraFrame(scene.cameraAt(0.0));
    const Image img = nearRenderer().render(cam, scene.models, sprites(scene, true),
                                            scene.render.background, counting, &near);
    Image ref(cam.width, cam.height, scene.render.background);
    ReferenceOptions cellByCell;
    cellByCell.earlyDepthTest = false;
    cellByCell.skipEmptyBricks = false;
    ReferenceStats rs;
    renderReference(scene.models, sprites(scene, false), ref, &rs, cellByCell);
    EXPECT_EQ(test::describeDifference(img, ref), "");
    EXPECT_EQ(near.voxelFetches, rs.voxelFetches);
    EXPECT_EQ(rs.brickFetches, 0u);
    EXPECT_GT(rs.voxelFetches, 0u);
}

} // namespace
} // namespace voxtier
