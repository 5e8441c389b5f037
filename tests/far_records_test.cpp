// The Vulkan far pass keeps what a frame's slot already holds (FarPass::record with a
// SpriteStore's history): an instance's record whose place holds the same entity's unchanged
// sprite, drawn from the same snapshot at the same device place with the same palette place, is
// not written again, and the draw order with the tile lists is last frame's while the same
// entities' sprites drew the same instances without moving on screen. Each frame that keeps them
// equals the same sprites and plan drawn by a renderer with Vulkan objects of its own that writes
// everything, pixel for pixel (colour, depth bits, id); what the frames bring: animation steps
// (another snapshot, the same order), moved entities, a camera move, a voxel edit (snapshots
// refreshed), cross-fades (copies of sprites, no store's), near sprites beside the far ones. And
// one far pass fed by two stores in turn (two scenes of the same entity ids) equals the CPU blit
// on every frame: a store's stamps say nothing of another's records. Keeping nothing would pass
// the images: the counts of kept records and orders fail it.
#include "compose/frame.hpp"
#include "compose/vulkan_frame.hpp"
#include "core/sprite_store.hpp"
#include "crowd_scenes.hpp"
#include "image_checks.hpp"
#include "impostor_cache/far_frame.hpp"
#include "impostor_cache/far_pass.hpp"
#include "impostor_cache/snapshot_cache.hpp"
#include "vulkan_test_env.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <memory>
#include <vector>

namespace voxtier {
namespace {

const auto* const kEnv = ::testing::AddGlobalTestEnvironment(new test::NearRendererEnvironment);

class FarRecordsKept : public test::VulkanTest {
  protected:
    /// Both ways of cutting the far pass that a device's auto choice may take: the tiles keep
    /// their lists with the order, the pass cut by sprite keeps the order alone.
    static constexpr FarTiles kCuts[] = {FarTiles::Coarse, FarTiles::Sprites};
    static FrameOptions options(bool shared, FarTiles tiles) {
        FrameOptions o;
        o.farTiles = tiles;
        if (shared) o.sharedNear = sharedNearRenderer();
        o.nearBackend = NearBackend::Vulkan;
        o.nearPixels = NearPixels::Compute;
        o.farBackend = FarBackend::Vulkan;
        o.costAwareBakes = false; // images must not depend on timing
        o.depthAndIds = true;     // compare every plane
        return o;
    }
};

TEST_F(FarRecordsKept, FramesThatKeepRecordsEqualFramesThatWriteEverything) {
    for (const FarTiles tiles : kCuts) {
        SCOPED_TRACE(tiles == FarTiles::Sprites ? "cut by sprite" : "coarse tiles");
        Scene s = test::stillSteppingArmy();
        FrameRenderer renderer(s, options(true, tiles));
        FrameRenderer everything(s, options(false, tiles));
        std::uint64_t keptRecords = 0, records = 0;
        int keptOrders = 0, keptWhole = 0, fadingFrames = 0, nearFrames = 0;
        for (int k = 0; k < 28; ++k) {
            const double t = k / 30.0;
            test::changeSteppingArmy(s, k);
            const RenderMode mode = k >= 18 ? RenderMode::Hybrid : RenderMode::Far;
            const FrameResult r = renderer.render(t, mode, k);
            FrameStats full;
            const Image expected =
                everything.draw(makeCameraFrame(s.cameraAt(t)), r.sprites, r.plan, &full);
            ASSERT_EQ(test::describeDifference(r.image, expected, "kept", "written"), "")
                << "frame " << k;
            ASSERT_GT(test::drawnPixels(expected), 0u) << "frame " << k;
            const FarPassStats& far = r.stats.vulkanFar;
            ASSERT_GT(far.sprites, 0u) << "frame " << k << ": the far pass drew";
            EXPECT_EQ(full.vulkanFar.recordsKept, 0u) << "frame " << k << ": nothing to keep";
            EXPECT_FALSE(full.vulkanFar.orderKept) << "frame " << k << ": nothing to keep";
            fadingFrames += r.stats.plan.fading > 0;
            nearFrames += r.stats.nearDrawn > 0;
            keptRecords += far.recordsKept;
            records += far.sprites;
            keptOrders += far.orderKept;
            keptWhole += far.recordsKept == far.sprites;
            if (k == 9) {
                EXPECT_EQ(far.recordsKept, 0u) << "the camera moved: every record changed";
                EXPECT_FALSE(far.orderKept) << "the camera moved: every depth changed";
            }
            if (k == 5 || k == 13) {
                EXPECT_FALSE(far.orderKept) << "frame " << k << ": tanks moved";
            }
        }
        EXPECT_GT(fadingFrames, 0) << "no cross-fade: no copy of a sprite was drawn";
        EXPECT_GT(nearFrames, 5) << "no near sprite beside the far ones";
        EXPECT_GT(keptWhole, 3) << "frames between animation steps keep every record";
        EXPECT_GT(keptOrders, 10) << "animation steps keep the draw order";
        EXPECT_GT(keptRecords * 4, records) << "a quarter of the records at least are kept";
    }
}

TEST_F(FarRecordsKept, OneFarPassFedByTwoStoresInTurnEqualsTheCpuBlit) {
    // Two scenes of the same models and entity ids, the second's tanks 1 m to the side: the same
    // tanks in view, the same instances in the same sequence, but their records, rectangles and
    // depths differ (with no store in the check, either the records or the order of the other
    // store's frame are taken, and the images differ).
    Scene a = test::stillSteppingArmy(), b = test::stillSteppingArmy();
    for (Entity& e : b.entities) e.position += glm::dvec3(1.0, 0.0, 0.0);
    b.models = a.models;
    {
        SpriteStore sa, sb;
        (void)sa.update(a, makeCameraFrame(a.camera), 0.0);
        (void)sb.update(b, makeCameraFrame(b.camera), 0.0);
        const auto va = sa.visibleIds(), vb = sb.visibleIds();
        ASSERT_TRUE(std::equal(va.begin(), va.end(), vb.begin(), vb.end()))
            << "the same tanks in view";
    }
    for (const FarTiles tiles : kCuts) {
        SCOPED_TRACE(tiles == FarTiles::Sprites ? "cut by sprite" : "coarse tiles");
        FarPass pass(nearRenderer().frames(), tiles);
        SnapshotCache cache;
        SpriteStore storeA, storeB;
        std::uint64_t kept = 0;
        // Turns that hand each slot (two or three frames in flight) frames of both stores.
        const char turns[] = "AABABBAAABBBAB";
        for (int k = 0; turns[k]; ++k) {
            const Scene& s = turns[k] == 'A' ? a : b;
            SpriteStore& store = turns[k] == 'A' ? storeA : storeB;
            const CameraFrame cam = makeCameraFrame(s.camera);
            (void)store.update(s, cam, 0.0); // still tanks at time 0: nothing changes after
            const std::span<const SpriteSetup> sprites = store.sprites();
            std::vector<FarRequest> requests;
            for (const std::uint32_t i : store.visibleIds()) requests.push_back({&sprites[i], {}});
            const FarBatch batch = prepareFarBatch(s.models, requests, cache, ViewSet::Cube26);
            const SpriteHistory history = store.history();
            VulkanFrameRequest request;
            request.camera = &cam;
            request.models = &s.models;
            request.far = &batch;
            request.history = &history;
            const VulkanFrameResult r = drawVulkanFrame(nearRenderer(), &pass, request);
            Image cpu(cam.width, cam.height, 0);
            drawFarSprites(s.models, requests, cache, ViewSet::Cube26, cpu);
            ASSERT_EQ(test::describeDifference(r.image, cpu, "vulkan far", "cpu far"), "")
                << "frame " << k << " (" << turns[k] << ")";
            ASSERT_GT(r.far.sprites, 0u);
            kept += r.far.recordsKept;
        }
        EXPECT_GT(kept, 0u) << "a store's own records are kept";
    }
}

} // namespace
} // namespace voxtier
