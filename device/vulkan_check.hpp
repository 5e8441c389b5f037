#pragma once
// The one error channel for Vulkan calls (core/error.hpp lists the channels): every call that
// returns a VkResult goes through VK_CHECK, which throws VulkanError naming the call, the
// result and the source line. The renderer never continues after a failed call, so there is
// no "log and carry on" variant.
#include <vulkan/vulkan.h>

#include <stdexcept>
#include <string>

namespace voxtier {

/// A Vulkan call failed, or no usable device exists. what() is one line.
class VulkanError : public std::runtime_error {
  public:
    explicit VulkanError(const std::string& message, VkResult result = VK_ERROR_UNKNOWN)
        : std::runtime_error(message), result_(result) {}
    VkResult result() const { return result_; }

  private:
    VkResult result_;
};

const char* vkResultName(VkResult r);

[[noreturn]] void throwVulkanFailure(VkResult r, const char* call, const char* file, int line);

} // namespace voxtier

/// VK_CHECK(vkCreateBuffer(...)): throws VulkanError unless the call returned VK_SUCCESS.
#define VK_CHECK(call)                                                                             \
    do {                                                                                           \
        const VkResult vtResult_ = (call);                                                         \
        if (vtResult_ != VK_SUCCESS)                                                               \
            ::voxtier::throwVulkanFailure(vtResult_, #call, __FILE__, __LINE__);                   \
    } while (0)
