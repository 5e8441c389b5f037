// The Vulkan near tier's early depth test (issue 25, NearOptions::earlyDepthTest): the sprites are
// drawn front to back, hull sprites rasterised flat at their own depth so that the depth test runs
// before the fragment shader; traced in compute (NearPixels::Compute, the default), the same order
// lets a sprite skip the pixels a nearer one holds. The image must not change by a single bit of
// colour, depth or id, on every scene, proxy and rate, both ways of tracing per-pixel sprites, in
// whole hybrid frames with cross-fades, with equal depths, through the near plane and at 100,000
// entities.
#include "compose/frame.hpp"
#include "core/scene_loader.hpp"
#include "crowd_scenes.hpp"
#include "image_checks.hpp"
#include "impostor_cache/far_pass.hpp"
#include "source_tree.hpp"
#include "vulkan_test_env.hpp"

#include <gtest/gtest.h>

namespace voxtier {
namespace {

const auto* const kEnv = ::testing::AddGlobalTestEnvironment(new test::NearRendererEnvironment);

using test::sourcePath;
class VulkanCull : public test::VulkanTest {};

/// Draws `s` at time t without culling and with it; expects the culled image equal to the
/// unculled one and to the CPU reference. Returns the fragment shader invocations without and
/// with culling (pipeline statistics; 0 where the device has none).
std::pair<std::uint64_t, std::uint64_t> expectSameImage(NearRenderer& renderer, const Scene& s,
                                                        double t, NearPixels pixels,
                                                        NearProxy proxy, NearRate rate,
                                                        const std::string& what) {
    const CameraFrame cam = makeCameraFrame(s.cameraAt(t));
    const std::vector<SpriteSetup> sprites = setupSprites(s, cam, t);
    Image reference(cam.width, cam.height, s.render.background);
    renderReference(s.models, sprites, reference);
    NearOptions plain;
    plain.pixels = pixels;
    plain.proxy = proxy;
    plain.rate = rate;
    plain.earlyDepthTest = false;
    NearStats plainStats, culledStats;
    const Image whole =
        renderer.render(cam, s.models, sprites, s.render.background, plain, &plainStats);
    EXPECT_EQ(plainStats.earlyDepthSprites, 0u) << what;
    EXPECT_EQ(test::describeDifference(whole, reference), "") << what;
    NearOptions culled = plain;
    culled.earlyDepthTest = true;
    const Image img =
        renderer.render(cam, s.models, sprites, s.render.background, culled, &culledStats);
    EXPECT_EQ(test::describeDifference(img, whole, "culled", "whole"), "") << what;
    if (pixels == NearPixels::Raster && proxy == NearProxy::Hull && rate == NearRate::Fragment) {
        EXPECT_GT(culledStats.earlyDepthSprites, 0u) << what;
    }
    EXPECT_EQ(culledStats.pixelsInCompute, pixels == NearPixels::Compute) << what;
    // The counting variant writes memory, so llvmpipe tests its depth late: the same image.
    culled.countSteps = true;
    const Image counted = renderer.render(cam, s.models, sprites, s.render.background, culled);
    EXPECT_EQ(test::describeDifference(counted, whole, "culled, counting", "whole"), "") << what;
    return {plainStats.fragmentInvocations, culledStats.fragmentInvocations};
}

class VulkanCullOnSceneFiles : public VulkanCull,
                               public ::testing::WithParamInterface<const char*> {};

TEST_P(VulkanCullOnSceneFiles, SameImageWithEveryProxyAndRate) {
    Scene s = loadScene(sourcePath(GetParam()));
    if (s.camera.width > 480) s.camera.width /= 2, s.camera.height /= 2;
    const int frames = s.path ? s.path->frameCount() : 1;
    for (const int f : {0, frames / 2}) {
        const double t = s.path ? s.timeOfFrame(f) : 0.0;
        for (NearRate rate : {NearRate::Fragment, NearRate::Auto}) {
            const std::string at = std::string(GetParam()) + " frame " + std::to_string(f) + " ";
            expectSameImage(nearRenderer(), s, t, NearPixels::Compute, NearProxy::Hull, rate,
                            at + "compute " + toString(rate));
            for (NearProxy proxy : {NearProxy::Hull, NearProxy::Quad}) {
                const std::string what =
                    at + (proxy == NearProxy::Hull ? "hull " : "quad ") + toString(rate);
                const auto [whole, culled] =
                    expectSameImage(nearRenderer(), s, t, NearPixels::Raster, proxy, rate, what);
                std::printf("%s: fragment shader invocations %llu whole, %llu culled\n",
                            what.c_str(), (unsigned long long)whole, (unsigned long long)culled);
            }
        }
    }
}

INSTANTIATE_TEST_SUITE_P(
    Scenes, VulkanCullOnSceneFiles,
    ::testing::Values("scenes/default.json", "scenes/golden/arrows.json",
                      "scenes/golden/crowd.json", "scenes/golden/equal_depth.json",
                      "scenes/golden/far_origin.json", "scenes/golden/topdown.json",
                      "scenes/bench/tank_army.json", "scenes/bench/rts_pan.json",
                      "scenes/bench/street.json", "scenes/bench/vox_crowd.json"));

// Equal depths everywhere (three entities in one place: the id rule alone decides), rows at one
// view depth, and a first row whose sprites cross the near plane.
TEST_F(VulkanCull, EqualDepthStacksAndSpritesThroughTheNearPlane) {
    const Scene s = test::equalDepthStacks();
    for (NearRate rate : {NearRate::Fragment, NearRate::Auto}) {
        expectSameImage(nearRenderer(), s, 0.0, NearPixels::Compute, NearProxy::Hull, rate,
                        "equal-depth stacks, compute");
        for (NearProxy proxy : {NearProxy::Hull, NearProxy::Quad})
            expectSameImage(nearRenderer(), s, 0.0, NearPixels::Raster, proxy, rate,
                            "equal-depth stacks");
    }
}

// Whole frames through compose/: the hybrid with cross-fades (dithered halves of one entity at
// one depth in both tiers), near tier on Vulkan, far tier on the CPU and on Vulkan, with
// FrameOptions::earlyDepthTest on (the default) and off.
TEST_F(VulkanCull, HybridFramesWithCrossFadesAreUnchanged) {
    Scene s = test::crossFadeCorridor();
    for (FarBackend far : {FarBackend::Cpu, FarBackend::Vulkan}) {
        if (far == FarBackend::Vulkan && !FarPass::supported(nearRenderer().device())) continue;
        FrameOptions on, off;
        on.nearBackend = off.nearBackend = NearBackend::Vulkan;
        on.farBackend = off.farBackend = far;
        on.costAwareBakes = off.costAwareBakes = false;
        off.earlyDepthTest = false;
        Scene copy = s;
        FrameRenderer culled(s, on), whole(copy, off);
        int fading = 0;
        for (int f = 0; f < s.path->frameCount(); f += 2) {
            const FrameResult ra = culled.render(s.timeOfFrame(f), RenderMode::Hybrid, f);
            const FrameResult rb = whole.render(s.timeOfFrame(f), RenderMode::Hybrid, f);
            fading += ra.stats.plan.fading;
            EXPECT_EQ(test::describeDifference(ra.image, rb.image, "culled", "whole"), "")
                << "frame " << f << (far == FarBackend::Vulkan ? " far on Vulkan" : "");
        }
        EXPECT_GT(fading, 0) << "the path must cross-fade somewhere";
    }
}

// The tank army at 100,000 entities, 320x180, near tier on Vulkan per pixel.
TEST_F(VulkanCull, OneHundredThousandTanks) {
    const Scene s = test::tankArmy(100000, 320, 180);
    ASSERT_EQ(s.entities.size(), 100000u);
    const CameraFrame cam = makeCameraFrame(s.cameraAt(0.0));
    const std::vector<SpriteSetup> sprites = setupSprites(s, cam, 0.0);
    NearOptions plainOptions, culledOptions;
    plainOptions.rate = culledOptions.rate = NearRate::Fragment;
    plainOptions.pixels = culledOptions.pixels = NearPixels::Raster;
    plainOptions.earlyDepthTest = false;
    NearStats a, b;
    const Image culled =
        nearRenderer().render(cam, s.models, sprites, s.render.background, culledOptions, &a);
    const Image whole =
        nearRenderer().render(cam, s.models, sprites, s.render.background, plainOptions, &b);
    EXPECT_EQ(test::describeDifference(culled, whole, "culled", "whole"), "");
    // The same sprites traced in compute, front to back, skipping the pixels nearer ones hold.
    NearOptions computeOptions = culledOptions;
    computeOptions.pixels = NearPixels::Compute;
    const Image traced =
        nearRenderer().render(cam, s.models, sprites, s.render.background, computeOptions);
    EXPECT_EQ(test::describeDifference(traced, whole, "traced in compute", "whole"), "");
    EXPECT_GT(a.earlyDepthSprites, a.sprites * 9 / 10);
    std::printf("100,000 tanks at 320x180: %llu of %llu sprites flat, fragment shader invocations "
                "%llu culled / %llu whole\n",
                (unsigned long long)a.earlyDepthSprites, (unsigned long long)a.sprites,
                (unsigned long long)a.fragmentInvocations,
                (unsigned long long)b.fragmentInvocations);
}

} // namespace
} // namespace voxtier
