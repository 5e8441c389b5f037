#pragma once
// Helpers for the tests of device/ that record and submit their own commands
// (staging_test, pass_timer_test).
#include "device/vulkan_device.hpp"

namespace voxtier::test {

/// A validated device that reports into its log instead of stderr.
inline VulkanDeviceOptions validatedDevice(bool forceStaging = false) {
    VulkanDeviceOptions o;
    o.validation = true;
    o.echoMessages = false;
    o.forceStaging = forceStaging;
    return o;
}

/// One primary command buffer, recording from construction; submit() ends it, submits it, waits
/// for it and begins it again.
struct CommandRecorder {
    VulkanDevice& device;
    VkCommandBuffer cb;
    explicit CommandRecorder(VulkanDevice& d) : device(d), cb(d.allocateCommandBuffer()) {
        begin();
    }
    ~CommandRecorder() { device.freeCommandBuffer(cb); }
    CommandRecorder(const CommandRecorder&) = delete;
    CommandRecorder& operator=(const CommandRecorder&) = delete;
    void begin() {
        VkCommandBufferBeginInfo bi{VK_STRUCTURE_TYPE_COMMAND_BUFFER_BEGIN_INFO};
        bi.flags = VK_COMMAND_BUFFER_USAGE_ONE_TIME_SUBMIT_BIT;
        VK_CHECK(vkBeginCommandBuffer(cb, &bi));
    }
    void submit() {
        VK_CHECK(vkEndCommandBuffer(cb));
        device.submitAndWait(cb);
        VK_CHECK(vkResetCommandBuffer(cb, 0));
        begin();
    }
};

} // namespace voxtier::test
