#pragma once
// What a caller outside device/ needs to configure and inspect the Vulkan device, without
// including Vulkan headers (DESIGN.md §1: Vulkan stays inside device/ and the tiers' GPU passes).
#include <cstddef>
#include <mutex>
#include <string>
#include <vector>

namespace voxtier {

/// The message (what() of the VulkanError) when the loader finds no usable device and every
/// driver manifest's library loads; when one does not, the message names it instead
/// (noVulkanDeviceMessage(), device/icd_diagnosis.hpp).
inline constexpr const char* kNoVulkanDeviceMessage =
    "no Vulkan device: install mesa-vulkan-drivers for the CPU rasterizer lavapipe";

struct VulkanDeviceOptions {
    /// Enable VK_LAYER_KHRONOS_validation (also on when the environment has VOXTIER_VALIDATION=1).
    bool validation = false;
    /// With validation: also run synchronization validation (missing or wrong barriers).
    bool synchronizationValidation = true;
    /// Print each validation message to stderr as it arrives (tests read the log instead).
    bool echoMessages = true;
    /// Buffers the shaders read are uploaded through the staging ring even where the host could
    /// write them directly (also on when the environment has VOXTIER_FORCE_STAGING=1): exercises
    /// the discrete-GPU upload path on lavapipe or an integrated GPU.
    bool forceStaging = false;
};

/// What the Vulkan loader offers the near tier, found without creating a device: the device a
/// NearRenderer would pick (a GPU first, then a CPU implementation such as Mesa's lavapipe).
struct VulkanProbe {
    bool found = false;   ///< a Vulkan 1.2 device with a graphics queue exists
    bool cpu = false;     ///< it is a CPU implementation (VK_PHYSICAL_DEVICE_TYPE_CPU)
    std::string name;     ///< its name, e.g. "llvmpipe (LLVM 15.0.6, 256 bits)"
    bool float64 = false; ///< it has shaderFloat64 (what the far pass needs)
    std::string whyNone;  ///< when !found: the loader's answer, one line
};
/// Creates a Vulkan instance, looks at its devices and destroys it again (a few ms). Never throws.
VulkanProbe probeVulkanDevice();

/// True when the environment variable VOXTIER_VALIDATION is set to 1.
bool validationRequestedByEnvironment();
/// True when the environment variable VOXTIER_FORCE_STAGING is set to 1.
bool forcedStagingRequestedByEnvironment();

/// Warnings and errors from the validation layer and the loader. Shared, so it can outlive the
/// device: leak reports arrive while vkDestroyDevice / vkDestroyInstance run.
class VulkanMessageLog {
  public:
    void add(std::string message);
    std::size_t count() const;
    std::vector<std::string> messages() const;
    /// All messages, one per line (for test failure output).
    std::string joined() const;

  private:
    mutable std::mutex mutex_;
    std::vector<std::string> messages_;
};

} // namespace voxtier
