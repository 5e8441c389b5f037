// Frames in flight (FrameRenderer::submit / finish): a sequence drawn with frame k+1 submitted
// before frame k is read back gives the images of the same frames drawn one at a time, pixel for
// pixel (colour, depth bits, id), on Vulkan all-near and hybrid with the far pass, and the
// validation layer stays silent. What the slots share (the voxel atlas, the palettes, the cell
// store, the pixel words) grows while an earlier frame still reads it: the scene's path brings
// new models and frames near as it goes, so that growth happens here, and a buffer freed under a
// frame in flight is a validation error ("in use by a command buffer").
#include "compose/frame.hpp"
#include "core/scene_loader.hpp"
#include "image_checks.hpp"
#include "source_tree.hpp"
#include "vulkan_test_env.hpp"

#include <gtest/gtest.h>

#include <memory>
#include <vector>

namespace voxtier {
namespace {

const auto* const kEnv = ::testing::AddGlobalTestEnvironment(new test::NearRendererEnvironment);

class FramesInFlight : public test::VulkanTest {
  protected:
    static Scene scene() {
        Scene s = loadScene(test::sourcePath("scenes/default.json"));
        s.camera.width = 320; // a quarter of the pixels: lavapipe is the device here
        s.camera.height = 180;
        return s;
    }
    static FrameOptions options(FarBackend far) {
        FrameOptions o;
        // The test process's validated renderer, not owned by the FrameRenderers.
        o.sharedNear = sharedNearRenderer();
        o.nearBackend = NearBackend::Vulkan;
        o.nearPixels = NearPixels::Compute; // a GPU's default (Auto draws on lavapipe)
        o.farBackend = far;
        o.costAwareBakes = false; // images must not depend on timing
        o.depthAndIds = true;     // compare every plane
        return o;
    }
    /// Times along the default scene's path (0..5 s), so the near set changes from frame to frame.
    static std::vector<double> times() { return {0.0, 0.9, 1.8, 2.7, 3.6, 4.5, 5.0}; }

    /// The frames drawn one at a time, then with two in flight, by fresh renderers.
    static void expectSameInFlight(RenderMode mode, FarBackend far) {
        Scene one = scene(), two = scene();
        FrameRenderer sequential(one, options(far));
        std::vector<Image> expected;
        std::vector<std::vector<EntityPlan>> plansA, plansB;
        for (std::size_t k = 0; k < times().size(); ++k) {
            FrameResult r = sequential.render(times()[k], mode, int(k));
            plansA.emplace_back(r.plan.begin(), r.plan.end());
            expected.push_back(std::move(r.image));
        }

        FrameRenderer pipelined(two, options(far));
        std::vector<FrameRenderer::PendingFrame> inFlight;
        std::vector<Image> got;
        for (std::size_t k = 0; k < times().size(); ++k) {
            inFlight.push_back(pipelined.submit(times()[k], mode, int(k)));
            if (inFlight.size() == 2) {
                FrameResult r = pipelined.finish(std::move(inFlight.front()));
                plansB.emplace_back(r.plan.begin(), r.plan.end());
                got.push_back(std::move(r.image));
                inFlight.erase(inFlight.begin());
            }
        }
        {
            FrameResult r = pipelined.finish(std::move(inFlight.front()));
            plansB.emplace_back(r.plan.begin(), r.plan.end());
            got.push_back(std::move(r.image));
        }
        // The same plans: the images differ, if at all, on the device's side.
        for (std::size_t k = 0; k < plansA.size(); ++k)
            EXPECT_TRUE(plansA[k] == plansB[k]) << "frame " << k << ": the plans differ";
        ASSERT_EQ(got.size(), expected.size());
        std::size_t drawn = 0;
        for (std::size_t k = 0; k < got.size(); ++k) {
            EXPECT_EQ(test::describeDifference(got[k], expected[k], "in flight", "one at a time"),
                      "")
                << "frame " << k << " (t=" << times()[k] << " s)";
            drawn += test::drawnPixels(expected[k]);
        }
        EXPECT_GT(drawn, 0u) << "the frames drew nothing";
    }
};

TEST_F(FramesInFlight, AllNearOnVulkanGivesTheImagesOfOneFrameAtATime) {
    expectSameInFlight(RenderMode::Near, FarBackend::Vulkan);
}

TEST_F(FramesInFlight, HybridWithTheFarPassGivesTheImagesOfOneFrameAtATime) {
    expectSameInFlight(RenderMode::Hybrid, FarBackend::Vulkan);
}

} // namespace
} // namespace voxtier
