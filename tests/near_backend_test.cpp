// --near-backend auto (issue 24): the loader probe sees the device the Vulkan near tier uses; auto
// draws hybrid frames with the CPU reference where that device is a CPU (lavapipe here) and with
// Vulkan where it is a GPU, says so in its frame figures, and the image is the one the forced
// Vulkan near tier draws, pixel for pixel.
#include "compose/frame.hpp"
#include "core/scene_loader.hpp"
#include "image_checks.hpp"
#include "source_tree.hpp"
#include "volumetric/near_renderer.hpp"
#include "vulkan_test_env.hpp"

#include <gtest/gtest.h>

#include <memory>

namespace voxtier {
namespace {

const auto* const kEnv = ::testing::AddGlobalTestEnvironment(new test::NearRendererEnvironment);

class NearBackendAuto : public test::VulkanTest {};

TEST_F(NearBackendAuto, ProbeFindsTheDeviceTheNearTierUses) {
    const VulkanProbe probe = probeVulkanDevice();
    ASSERT_TRUE(probe.found) << probe.whyNone;
    EXPECT_EQ(probe.name, nearRenderer().deviceName());
    EXPECT_EQ(probe.cpu, nearRenderer().deviceIsCpu());
}

TEST_F(NearBackendAuto, DrawsWithTheFasterBackendAndTheForcedVulkanImage) {
    // The default scene's first frame: 27 near sprites, the rest far; no cost bound (timing).
    Scene autoScene = loadScene(test::sourcePath("scenes/default.json"));
    Scene vulkanScene = loadScene(test::sourcePath("scenes/default.json"));
    // The test environment's device, shared without ownership (it outlives both renderers).
    const std::shared_ptr<NearRenderer> shared(&nearRenderer(), [](NearRenderer*) {});
    FrameOptions o;
    o.costAwareBakes = false;
    o.sharedNear = shared;
    FrameOptions forced = o;
    forced.nearBackend = NearBackend::Vulkan;
    FrameRenderer autoRenderer(autoScene, o), vulkanRenderer(vulkanScene, forced);
    const FrameResult a = autoRenderer.render(0.0, RenderMode::Hybrid);
    const FrameResult v = vulkanRenderer.render(0.0, RenderMode::Hybrid);
    ASSERT_GT(a.stats.nearDrawn, 0);
    const bool gpu = !nearRenderer().deviceIsCpu();
    EXPECT_EQ(autoRenderer.nearBackend(), gpu ? NearBackend::Vulkan : NearBackend::Reference);
    EXPECT_EQ(a.stats.nearOnVulkan, gpu ? 1 : 0);
    EXPECT_EQ(v.stats.nearOnVulkan, 1);
    EXPECT_EQ(vulkanRenderer.nearBackend(), NearBackend::Vulkan);
    EXPECT_EQ(vulkanRenderer.nearBackendChoice(), ""); // given, not chosen
    EXPECT_NE(autoRenderer.nearBackendChoice().find(nearRenderer().deviceName()), std::string::npos)
        << autoRenderer.nearBackendChoice();
    EXPECT_EQ(a.stats.nearDrawn, v.stats.nearDrawn);
    EXPECT_EQ(test::describeDifference(v.image, a.image, "vulkan", "auto"), "");
}

} // namespace
} // namespace voxtier
