#pragma once
// The near tier on Vulkan as one object: a Vulkan device, its frames (device/gpu_frame.hpp) and the
// near passes (volumetric/near_passes.hpp). render() draws a frame of near sprites and reads it
// back; compose/ records other tiers' passes into the same frames (frames(), passes()).
// Every visible sprite is one instance of the frame's instanced draw of its proxy polygon
// (NearProxy), equal depths in ascending entity id, into an R32_UINT colour target (the kernel's
// packed RGBA8), an R32_UINT entity-id target and a D32_SFLOAT reversed-Z depth target (test
// GREATER: at equal depth the first, lower-id fragment stays, exactly like Image::writeIfNearer).
// The fragment shader runs the shared kernel (core/sprite_kernel.h), so the image equals the CPU
// reference pixel for pixel. Voxels live in one 3D atlas (volumetric/voxel_residency.hpp).
#include "core/camera.hpp"
#include "core/image.hpp"
#include "core/sprite.hpp"
#include "core/voxel_model.hpp"
#include "device/gpu_frame.hpp"
#include "device/vulkan_device.hpp"
#include "device/vulkan_options.hpp"
#include "volumetric/near_passes.hpp"

#include <memory>
#include <span>
#include <string>
#include <vector>

namespace voxtier {

/// Where one Vulkan frame's time went: the device time of its named passes and the host's waits.
struct GpuFrameReport {
    std::vector<PassTime> passes; ///< device times, in begin order (empty without timestamps)
    GpuFrameHostTimes host;
    double recordMs = 0.0; ///< host: preparing and recording the passes (uploads written)
    /// The device time of every pass called `name`, summed (nullopt: none was timed).
    std::optional<double> ms(std::string_view name) const;
};
/// The report of a finished frame (its timer's results and the host times it measured).
GpuFrameReport reportOf(GpuFrame& frame, double recordMs);

class NearRenderer {
  public:
    /// Creates the Vulkan device (throws VulkanError, e.g. with noVulkanDeviceMessage()).
    explicit NearRenderer(const VulkanDeviceOptions& options = {},
                          std::shared_ptr<VulkanMessageLog> log = nullptr);
    ~NearRenderer();
    NearRenderer(const NearRenderer&) = delete;
    NearRenderer& operator=(const NearRenderer&) = delete;

    /// Name of the Vulkan device in use (e.g. "llvmpipe (LLVM 15.0.6, 256 bits)").
    const std::string& deviceName() const;
    bool deviceIsCpu() const;
    bool validationEnabled() const;
    const std::shared_ptr<VulkanMessageLog>& messageLog() const;

    VulkanDevice& device() { return device_; }
    GpuFrames& frames() { return frames_; }
    NearPasses& passes() { return passes_; }

    /// Draws every visible sprite of `sprites` into a fresh camera-sized image cleared to
    /// `background` (depth 0, no entity). Sprite order does not matter: they are drawn in
    /// ascending entity id at equal depths. Models are indexed by SpriteSetup::model.
    Image render(const CameraFrame& camera, const std::vector<std::shared_ptr<VoxelModel>>& models,
                 std::span<const SpriteSetup* const> sprites, Rgba8 background,
                 const NearOptions& options = {}, NearStats* stats = nullptr,
                 GpuFrameReport* report = nullptr);
    Image render(const CameraFrame& camera, const std::vector<std::shared_ptr<VoxelModel>>& models,
                 const std::vector<SpriteSetup>& sprites, Rgba8 background,
                 const NearOptions& options = {}, NearStats* stats = nullptr,
                 GpuFrameReport* report = nullptr);

    /// Voxel bytes uploaded to the atlas since construction.
    std::uint64_t totalBytesUploaded() const;

  private:
    VulkanDevice device_;
    GpuFrames frames_;
    NearPasses passes_;
};

} // namespace voxtier
