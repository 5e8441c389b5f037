#pragma once
// Steps 3-5 of the frame recipe on Vulkan: one GpuFrame (device/gpu_frame.hpp) into which the
// near tier records its passes (volumetric/near_passes.hpp) and, after them, the far tier its far
// pass (impostor_cache/far_pass.hpp), submitted once (in two parts where the far sprites are
// found while the device draws the near ones: farAfterNear) and read back once. The far pass
// composes into the near tier's planes by the same depth/id rule as the CPU blit into the near
// image, so the image is the CPU tiers' bit for bit.
#include "core/camera.hpp"
#include "core/image.hpp"
#include "core/sprite.hpp"
#include "impostor_cache/far_batch.hpp"
#include "impostor_cache/far_pass.hpp"
#include "volumetric/near_renderer.hpp"

#include <functional>
#include <memory>
#include <span>
#include <vector>

namespace voxtier {

struct VulkanFrameRequest {
    const CameraFrame* camera = nullptr;
    const std::vector<std::shared_ptr<VoxelModel>>* models = nullptr;
    std::span<const SpriteSetup* const> nearSprites;
    /// Where the sprites, near and far, are a SpriteStore's (copies aside): what changed when, so
    /// that both tiers write only what changed (NearPasses::record, FarPass::record). Null:
    /// everything is written.
    const SpriteHistory* history = nullptr;
    /// Far sprites drawn by the far pass after the near ones (null: none). Needs a FarPass.
    const FarBatch* far = nullptr;
    /// Instead of `far`: the far sprites found while the device draws the near ones. The near
    /// passes are submitted first (GpuFrame::submitSoFar), then this is called (the far tier's
    /// lookups and bakes, on the host), then the far pass records what it returns (null: none)
    /// and the rest is submitted. Its time is not the frame's recording (recordMs).
    std::function<const FarBatch*()> farAfterNear;
    Rgba8 clear = 0; ///< what the planes start as (the background, or a transparent one)
    NearOptions near;
    /// Read the planes back into FrameResult's image (false: draw and time the frame only).
    bool readBack = true;
    /// Read back depth and ids too (false: the colour plane alone).
    bool depthAndIds = true;
};

struct VulkanFrameResult {
    Image image; ///< empty without readBack
    NearStats near;
    FarPassStats far;
    GpuFrameReport report;
    double farRecordMs = 0.0; ///< host: the far pass's share of report.recordMs
};

/// A Vulkan frame recorded and submitted, not yet read back: the host may prepare the next frame
/// while the device draws this one (GpuFrames holds two in flight).
struct VulkanFrameInFlight {
    NearRenderer* near = nullptr;
    GpuFrame* frame = nullptr;
    NearOptions nearOptions;
    bool depthAndIds = true;
    VulkanFrameResult result; ///< the host's counts so far
    double recordMs = 0.0;
};

/// Records one Vulkan frame and submits it: the near passes for `request.nearSprites` (none: the
/// planes are only cleared), then the far pass for `request.far` (or what `farAfterNear`
/// returns, the near passes submitted before it is called) on `farPass`, then the readback's
/// copy. Nothing of `request` is needed after it returns.
VulkanFrameInFlight submitVulkanFrame(NearRenderer& near, FarPass* farPass,
                                      const VulkanFrameRequest& request);
/// Waits for the frame and reads it back (frames finish in the order they were submitted).
VulkanFrameResult finishVulkanFrame(VulkanFrameInFlight&& frame);
/// Both at once.
VulkanFrameResult drawVulkanFrame(NearRenderer& near, FarPass* farPass,
                                  const VulkanFrameRequest& request);

} // namespace voxtier
