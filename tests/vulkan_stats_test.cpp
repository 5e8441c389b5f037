// What the near tier measures and its measured alternatives: the step-counting shader variant
// counts exactly the voxel reads the CPU reference makes; one draw per entity gives the same
// image as the single instanced draw; the rasterised proxy box only ever loses pixels (the
// outline pixels its perspective projection misses at close range), never changes one.
#include "core/procedural.hpp"
#include "core/scene_loader.hpp"
#include "image_checks.hpp"
#include "source_tree.hpp"
#include "vulkan_test_env.hpp"

#include <gtest/gtest.h>

namespace voxtier {
namespace {

const auto* const kEnv = ::testing::AddGlobalTestEnvironment(new test::NearRendererEnvironment);

using test::VulkanTest;
class NearMeasurements : public VulkanTest {};

using test::sourcePath;

TEST_F(NearMeasurements, StepCounterVariantCountsExactlyTheReferenceVoxelReads) {
    for (const char* file : {"scenes/golden/crowd.json", "scenes/golden/arrows.json"})
        for (const test::NearWay& way : test::kNearWays) {
            const NearProxy proxy = way.proxy;
            const Scene s = loadScene(sourcePath(file));
            NearOptions counting = way.options();
            counting.countSteps = true;
            // The counting variant counts the fragment shader's reads: every sprite per pixel,
            // as the reference traces by default (cell-rate counts are in cell_rate tests).
            counting.rate = NearRate::Fragment;
            // The shader traces every pixel its proxy covers; so does the reference without its
            // early depth test, which skips pixels a nearer sprite already holds.
            ReferenceOptions everyPixel;
            everyPixel.earlyDepthTest = false;
            const auto r = test::renderBoth(nearRenderer(), s, 0.0, counting, everyPixel);
            const char* name = way.name;
            EXPECT_EQ(test::describeDifference(r.near, r.reference), "")
                << file << " " << name << ": the variant draws the same image";
            // Both proxies cover every pixel whose cell is in range (the quad all of cellRange, the
            // hull every cell that can be drawn), and the reference's rectangle does too: the GPU
            // and the CPU run the tracer on exactly the same cells.
            EXPECT_EQ(r.nearStats.voxelFetches, r.referenceStats.voxelFetches)
                << file << " " << name;
            if (way.pixels == NearPixels::Compute) {
                // The trace runs the kernel on every pixel of every rectangle, as the reference
                // without its early depth test.
                EXPECT_EQ(r.nearStats.kernelFragments, r.referenceStats.pixelsTested) << file;
                EXPECT_EQ(r.nearStats.fragmentInvocations, 0u) << file << ": nothing rasterised";
            } else if (proxy == NearProxy::Quad) {
                EXPECT_GE(r.nearStats.kernelFragments, r.referenceStats.pixelsInSprite) << file;
            }
            if (r.nearStats.fragmentInvocations > 0) {
                EXPECT_GE(r.nearStats.fragmentInvocations, r.nearStats.kernelFragments) << file;
            }
            std::printf(
                "%s %s: %llu fragments (pipeline statistics), %llu kernel fragments, %llu voxel "
                "reads (reference: %llu pixels tested, %llu in a sprite, %llu reads)\n",
                file, name, (unsigned long long)r.nearStats.fragmentInvocations,
                (unsigned long long)r.nearStats.kernelFragments,
                (unsigned long long)r.nearStats.voxelFetches,
                (unsigned long long)r.referenceStats.pixelsTested,
                (unsigned long long)r.referenceStats.pixelsInSprite,
                (unsigned long long)r.referenceStats.voxelFetches);
        }
}

TEST_F(NearMeasurements, OneDrawPerEntityGivesTheSameImageAsOneInstancedDraw) {
    const Scene s = loadScene(sourcePath("scenes/golden/equal_depth.json")); // ties need the order
    NearOptions perEntity;
    perEntity.pixels = NearPixels::Raster; // draws exist in the raster path alone
    perEntity.draws = NearDraws::PerEntity;
    perEntity.rate = NearRate::Fragment; // draws: cell-rate sprites are not rasterised
    const auto r = test::renderBoth(nearRenderer(), s, 0.0, perEntity);
    EXPECT_EQ(r.nearStats.drawCalls, r.nearStats.sprites);
    EXPECT_GT(r.nearStats.sprites, 1u);
    EXPECT_EQ(test::describeDifference(r.near, r.reference), "");
}

// The hull proxy (the default: the model box's parallel projection grown by the kernel's reach and
// 2 px) is exact like the quad, with fewer fragments: on every golden scene and the default scene.
// Proxies are rasterised for per-pixel sprites only (cell-rate ones are drawn by compute passes),
// so these measurements force the per-pixel rate.
TEST_F(NearMeasurements, HullProxyIsExactWithFewerFragmentsThanTheQuad) {
    for (const char* file :
         {"scenes/golden/arrows.json", "scenes/golden/crowd.json", "scenes/golden/equal_depth.json",
          "scenes/golden/far_origin.json", "scenes/golden/topdown.json", "scenes/default.json"}) {
        const Scene s = loadScene(sourcePath(file));
        NearOptions hull;
        hull.pixels = NearPixels::Raster; // proxies are rasterised in the raster path alone
        hull.proxy = NearProxy::Hull;
        hull.rate = NearRate::Fragment;
        const auto r = test::renderBoth(nearRenderer(), s, 0.0, hull);
        EXPECT_EQ(test::describeDifference(r.near, r.reference), "") << file;
        NearOptions quad;
        quad.pixels = NearPixels::Raster;
        quad.proxy = NearProxy::Quad;
        quad.rate = NearRate::Fragment;
        const auto q = test::renderBoth(nearRenderer(), s, 0.0, quad);
        EXPECT_LT(r.nearStats.fragmentInvocations, q.nearStats.fragmentInvocations) << file;
        std::printf("%s: hull %llu fragments, quad %llu\n", file,
                    (unsigned long long)r.nearStats.fragmentInvocations,
                    (unsigned long long)q.nearStats.fragmentInvocations);
    }
}

/// Every pixel where the box image differs from the reference is one the box lost: the reference
/// has an entity there, and the box image has background or something farther.
struct BoxLoss {
    std::size_t lost = 0, other = 0;
};
BoxLoss classifyBoxDifferences(const Image& box, const Image& reference) {
    BoxLoss l;
    for (std::size_t p = 0; p < box.pixelCount(); ++p) {
        if (box.color[p] == reference.color[p] && box.id[p] == reference.id[p] &&
            box.depth[p] == reference.depth[p])
            continue;
        const bool lost =
            reference.id[p] != kernel::VT_NO_ENTITY && box.depth[p] < reference.depth[p];
        (lost ? l.lost : l.other)++;
    }
    return l;
}

// CONTRACT.md §3.10: the rasterised box covers what its own perspective projection covers, while
// the sprite's rays are parallel; close to the camera the two differ and outline pixels at the
// silhouette are lost. Far away (or with the quad) nothing is lost.
TEST_F(NearMeasurements, BoxProxyOnlyLosesPixelsAndOnlyAtCloseRange) {
    const auto model = makeArrow(16);
    Scene s;
    s.render.sigma = 2.0;
    s.models = {model};
    Entity e;
    e.rotation = glm::angleAxis(0.6, glm::normalize(glm::dvec3(0.2, 1.0, 0.3)));
    s.entities.push_back(e);
    s.camera.width = 320;
    s.camera.height = 200;
    s.camera.fovYDeg = 60.0;
    s.camera.target = {0.0, 0.25, 0.0};
    NearOptions box;
    box.pixels = NearPixels::Raster;
    box.proxy = NearProxy::Box;
    box.rate = NearRate::Fragment; // the proxy is rasterised for per-pixel sprites only
    std::size_t lostClose = 0, lostFar = 0;
    for (double distance : {1.3, 1.6, 2.0, 8.0}) {
        for (double azimuth : {0.0, 0.8, 2.0}) {
            s.camera.position =
                s.camera.target + distance * glm::dvec3(std::sin(azimuth), 0.35, std::cos(azimuth));
            const auto r = test::renderBoth(nearRenderer(), s, 0.0, box);
            ASSERT_TRUE(r.sprites[0].visible());
            const BoxLoss l = classifyBoxDifferences(r.near, r.reference);
            EXPECT_EQ(l.other, 0u)
                << "distance " << distance << ": the box changed a pixel instead of losing it";
            (distance < 5.0 ? lostClose : lostFar) += l.lost;
        }
    }
    std::printf("box proxy: %zu pixels lost at 1.3-2 m, %zu at 8 m\n", lostClose, lostFar);
    EXPECT_GT(lostClose, 0u) << "expected the documented close-range loss";
    EXPECT_EQ(lostFar, 0u);
}

} // namespace
} // namespace voxtier
