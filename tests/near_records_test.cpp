// The Vulkan near tier keeps what a frame's slot already holds (NearPasses::record with a
// SpriteStore's history): a sprite record that holds the same entity's unchanged sprite is not
// written again (one that changed only its animation frame has that frame's fields written), the
// draw order is last frame's while no sprite was set up anew, and the residency's first showing
// of each model frame while no sprite changed at all. Each frame of a renderer that keeps them
// equals the same sprites and plan drawn by a renderer with Vulkan objects of its own that
// writes everything, pixel for pixel (colour, depth bits, id). The frames
// bring what changes records: animation steps, moved entities, a camera move, a voxel edit,
// cross-fades between the tiers (copies of sprites, no store's), and another renderer's frames
// of the same entities at another time written into the same slots (its stamps past this
// store's); both ways of tracing the per-pixel sprites. Keeping nothing would pass the images:
// the counts of kept records, orders and first showings fail it.
#include "compose/frame.hpp"
#include "crowd_scenes.hpp"
#include "image_checks.hpp"
#include "vulkan_test_env.hpp"

#include <gtest/gtest.h>

#include <memory>
#include <string>
#include <utility>
#include <vector>

namespace voxtier {
namespace {

const auto* const kEnv = ::testing::AddGlobalTestEnvironment(new test::NearRendererEnvironment);

class NearRecordsKept : public test::VulkanTest {
  protected:
    static FrameOptions options(NearPixels pixels, bool shared,
                                NearRecords records = NearRecords::Drawn) {
        FrameOptions o;
        if (shared) o.sharedNear = sharedNearRenderer();
        o.nearBackend = NearBackend::Vulkan;
        o.nearPixels = pixels;
        o.nearRecords = records;
        o.farBackend = FarBackend::Cpu;
        o.costAwareBakes = false; // images must not depend on timing
        o.depthAndIds = true;     // compare every plane
        return o;
    }
};

TEST_F(NearRecordsKept, FramesThatKeepRecordsEqualFramesThatWriteEverything) {
    // The records at their places in the draw order, and in the order given (NearRecords), each
    // way both ways of tracing; `everything` lays them out at their places.
    for (const auto& [pixels, layout] : {std::pair{NearPixels::Compute, NearRecords::Drawn},
                                         std::pair{NearPixels::Raster, NearRecords::Drawn},
                                         std::pair{NearPixels::Compute, NearRecords::Given},
                                         std::pair{NearPixels::Raster, NearRecords::Given}}) {
        SCOPED_TRACE(
            std::string(pixels == NearPixels::Compute ? "traced in compute" : "rasterised") +
            ", records " + toString(layout));
        Scene s = test::stillSteppingArmy();
        Scene other = s; // its own entities and camera, the same models
        FrameRenderer renderer(s, options(pixels, true, layout));
        FrameRenderer everything(s, options(pixels, false));
        // The same entities of the same models, on the same slots, 40 updates ahead of
        // `renderer`'s store (its records laid out the other way).
        FrameRenderer intruder(
            other, options(pixels, true,
                           layout == NearRecords::Drawn ? NearRecords::Given : NearRecords::Drawn));
        // At time 0 (frame 0 alone resident, as for `renderer`'s first frame).
        for (int k = 0; k < 40; ++k) (void)intruder.render(0.0, RenderMode::Near, k);

        std::uint64_t keptRecords = 0, patchedRecords = 0, records = 0;
        int keptOrders = 0, keptFirsts = 0, keptWhole = 0, drawnFrames = 0, fadingFrames = 0;
        for (int k = 0; k < 28; ++k) {
            const double t = k / 30.0;
            test::changeSteppingArmy(s, k);
            if (k == 16) (void)intruder.render(t + 0.4, RenderMode::Near, 16);
            const RenderMode mode = k >= 18 ? RenderMode::Hybrid : RenderMode::Near;
            // Frame 2 lays its records out the other way, in a slot the next frames keep from:
            // a record is kept where the same entity's sits at its index, whichever way.
            renderer.options().nearRecords =
                k != 2 ? layout
                       : (layout == NearRecords::Drawn ? NearRecords::Given : NearRecords::Drawn);
            const FrameResult r = renderer.render(t, mode, k);
            FrameStats full;
            const Image expected =
                everything.draw(makeCameraFrame(s.cameraAt(t)), r.sprites, r.plan, &full);
            ASSERT_EQ(test::describeDifference(r.image, expected, "kept", "written"), "")
                << "frame " << k;
            drawnFrames += test::drawnPixels(expected) > 0;
            fadingFrames += r.stats.plan.fading > 0;
            const NearStats& near = r.stats.vulkanNear;
            EXPECT_EQ(full.vulkanNear.recordsKept + full.vulkanNear.recordsPatched, 0u)
                << "frame " << k << ": nothing to keep";
            keptRecords += near.recordsKept;
            patchedRecords += near.recordsPatched;
            records += near.sprites;
            keptOrders += near.drawOrderKept;
            keptFirsts += near.firstShowingsKept;
            keptWhole += near.sprites > 0 && near.recordsKept == near.sprites;
            if (k == 9) {
                EXPECT_EQ(near.recordsKept + near.recordsPatched, 0u)
                    << "the camera moved: every record changed";
                EXPECT_FALSE(near.drawOrderKept) << "the camera moved: every depth changed";
                EXPECT_FALSE(near.firstShowingsKept) << "the camera moved: the order changed";
            }
        }
        EXPECT_EQ(drawnFrames, 28);
        EXPECT_GT(fadingFrames, 0) << "no cross-fade: no copy of a sprite was drawn";
        EXPECT_GT(keptWhole, 3) << "frames between animation steps keep every record";
        EXPECT_GT(keptOrders, 10) << "animation steps keep the draw order";
        EXPECT_GT(keptFirsts, 5) << "frames between steps keep the residency's first showings";
        EXPECT_GT(keptRecords * 4, records) << "a quarter of the records at least are kept";
        EXPECT_GT(patchedRecords, 240u) << "animation steps patch the records they find";
    }
}

} // namespace
} // namespace voxtier
