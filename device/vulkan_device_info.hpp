#pragma once
// What a report says about the Vulkan device the near tier would use (tools/gpu_check.sh,
// `voxtier check`), without Vulkan types (DESIGN.md §1).
#include <string>
#include <vector>

namespace voxtier {

struct VulkanDeviceInfo {
    bool found = false;
    std::string name;       ///< e.g. "NVIDIA H100 80GB HBM3", "llvmpipe (LLVM 15.0.6, 256 bits)"
    std::string type;       ///< "discrete GPU", "integrated GPU", "virtual GPU", "CPU", "other"
    std::string driver;     ///< driver name and info, e.g. "llvmpipe Mesa 22.3.6 (LLVM 15.0.6)"
    std::string apiVersion; ///< the Vulkan version the device offers, e.g. "1.3.230"
    std::string whyNone;    ///< when !found: the loader's answer, one line
    /// "NAME (TYPE; driver DRIVER; Vulkan VERSION)", or whyNone.
    std::string summary() const;
};
/// Describes the device probeVulkanDevice() picks (device/vulkan_options.hpp). Never throws.
VulkanDeviceInfo describeVulkanDevice();

/// Where each buffer class lives on the device a VulkanDevice picks (device/memory_policy.hpp),
/// one line per class: "ShaderRead: type 4 (DEVICE_LOCAL|HOST_VISIBLE|HOST_COHERENT), heap 0 of
/// 15.92 GiB, host writes directly". Honours VOXTIER_FORCE_STAGING. Empty when there is no
/// device; never throws.
std::vector<std::string> describeMemoryPlacements();

} // namespace voxtier
