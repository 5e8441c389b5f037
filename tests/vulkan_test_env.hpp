#pragma once
// The Vulkan near tier in tests: one validated renderer per test process, a fixture that
// fails a test on any validation message, and a frame drawn by both the reference and Vulkan.
#include "core/camera.hpp"
#include "core/image.hpp"
#include "core/scene.hpp"
#include "core/sprite.hpp"
#include "device/vulkan_options.hpp"
#include "volumetric/near_renderer.hpp"
#include "volumetric/reference_renderer.hpp"

#include <gtest/gtest.h>

#include <memory>
#include <vector>

namespace voxtier::test {

/// One NearRenderer per test process, shared by every Vulkan test in it: lavapipe JIT-compiles a
/// pipeline on first use, which would otherwise dominate the suite. Validation (with
/// synchronization validation) is always on; messages are recorded, not printed. There is no
/// "skip when no device": on a machine without Vulkan these tests fail, loudly.
/// Register it in each Vulkan test file with
///   const auto* kEnv = ::testing::AddGlobalTestEnvironment(new test::NearRendererEnvironment);
/// Its TearDown destroys the renderer and device and asserts that the layer reported nothing,
/// leaked objects included (those are reported while the device and instance are destroyed).
class NearRendererEnvironment : public ::testing::Environment {
  public:
    static NearRenderer& renderer() {
        if (!instance()) {
            VulkanDeviceOptions options;
            options.validation = true;
            options.echoMessages = false;
            instance() = std::make_unique<NearRenderer>(options, log());
        }
        return *instance();
    }
    static const std::shared_ptr<VulkanMessageLog>& log() {
        static const auto l = std::make_shared<VulkanMessageLog>();
        return l;
    }
    void TearDown() override {
        instance().reset();
        EXPECT_EQ(log()->count(), 0u) << "Vulkan validation / loader messages:\n"
                                      << log()->joined();
    }

  private:
    static std::unique_ptr<NearRenderer>& instance() {
        static std::unique_ptr<NearRenderer> r;
        return r;
    }
};

/// Fixture for Vulkan tests: every test ends with zero validation messages.
class VulkanTest : public ::testing::Test {
  protected:
    static NearRenderer& nearRenderer() { return NearRendererEnvironment::renderer(); }
    /// The same renderer for FrameOptions::sharedNear: shared with FrameRenderers, not owned.
    static std::shared_ptr<NearRenderer> sharedNearRenderer() {
        return std::shared_ptr<NearRenderer>(&nearRenderer(), [](NearRenderer*) {});
    }
    void TearDown() override {
        const auto& log = NearRendererEnvironment::log();
        EXPECT_EQ(log->count(), 0u) << "Vulkan validation messages:\n" << log->joined();
    }
};

/// A way the Vulkan near tier traces its per-pixel sprites: in compute (a GPU's default), or
/// rasterised over the hull proxy or the quad. Every way draws the reference image.
struct NearWay {
    const char* name;
    NearPixels pixels;
    NearProxy proxy;
    NearOptions options() const {
        NearOptions o;
        o.pixels = pixels;
        o.proxy = proxy;
        return o;
    }
};
inline constexpr NearWay kNearWays[] = {{"compute", NearPixels::Compute, NearProxy::Hull},
                                        {"hull", NearPixels::Raster, NearProxy::Hull},
                                        {"quad", NearPixels::Raster, NearProxy::Quad}};

/// NearOptions as a GPU takes them by default: the per-pixel sprites traced in compute
/// (NearPixels::Auto draws them instead on lavapipe, whose tests would then miss the GPUs' path).
inline NearOptions gpuDefaults() {
    NearOptions o;
    o.pixels = NearPixels::Compute;
    return o;
}

/// A frame of a scene through the CPU reference and through the Vulkan near tier (by default as
/// a GPU draws it).
struct NearAndReference {
    Image near, reference;
    std::vector<SpriteSetup> sprites;
    NearStats nearStats;
    ReferenceStats referenceStats;
};
inline NearAndReference renderBoth(NearRenderer& renderer, const Scene& scene, double time = 0.0,
                                   const NearOptions& options = gpuDefaults(),
                                   const ReferenceOptions& referenceOptions = {}) {
    NearAndReference r;
    const CameraFrame cam = makeCameraFrame(scene.cameraAt(time));
    r.sprites = setupSprites(scene, cam, time);
    r.reference = Image(cam.width, cam.height, scene.render.background);
    renderReference(scene.models, r.sprites, r.reference, &r.referenceStats, referenceOptions);
    r.near = renderer.render(cam, scene.models, r.sprites, scene.render.background, options,
                             &r.nearStats);
    return r;
}

} // namespace voxtier::test
