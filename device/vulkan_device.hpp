#pragma once
// A headless Vulkan 1.2 device: instance, physical-device choice (a GPU if there is one, else
// Mesa lavapipe on the CPU), one graphics queue, optional validation with every message
// recorded, and the few RAII resource wrappers the near renderer needs. No window, no
// swapchain. Not thread-safe: one thread drives a device.
#include "device/vulkan_check.hpp"
#include "device/vulkan_options.hpp"

#include <cstddef>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

namespace voxtier {

class VulkanDevice {
  public:
    /// Throws VulkanError(kNoVulkanDeviceMessage) when no Vulkan 1.2 device with a graphics
    /// queue exists, and VulkanError when validation is asked for but the layer is missing.
    explicit VulkanDevice(const VulkanDeviceOptions& options = {},
                          std::shared_ptr<VulkanMessageLog> log = nullptr);
    ~VulkanDevice();
    VulkanDevice(const VulkanDevice&) = delete;
    VulkanDevice& operator=(const VulkanDevice&) = delete;

    const std::string& name() const { return name_; }
    bool isCpu() const { return properties_.deviceType == VK_PHYSICAL_DEVICE_TYPE_CPU; }
    bool validationEnabled() const { return validation_; }
    const std::shared_ptr<VulkanMessageLog>& messageLog() const { return log_; }
    /// Pipeline statistics queries (fragments shaded) are available.
    bool hasPipelineStatistics() const { return pipelineStatistics_; }
    /// Atomics in fragment shaders (the DDA step counter) are available.
    bool hasFragmentAtomics() const { return fragmentAtomics_; }
    /// shaderFloat64 (enabled when present): what the far pass needs.
    bool hasFloat64() const { return float64_; }

    VkInstance instance() const { return instance_; }
    VkPhysicalDevice physicalDevice() const { return physical_; }
    VkDevice device() const { return device_; }
    VkQueue queue() const { return queue_; }
    std::uint32_t queueFamily() const { return queueFamily_; }
    const VkPhysicalDeviceProperties& properties() const { return properties_; }

    /// A memory type allowed by `typeBits` with all of `required`; throws when there is none.
    std::uint32_t memoryType(std::uint32_t typeBits, VkMemoryPropertyFlags required) const;

    /// A primary command buffer from the device's pool (reset and re-recorded by its owner).
    VkCommandBuffer allocateCommandBuffer();
    void freeCommandBuffer(VkCommandBuffer cb);
    /// Submits one recorded command buffer and blocks until the queue has executed it.
    void submitAndWait(VkCommandBuffer cb);

  private:
    std::shared_ptr<VulkanMessageLog> log_;
    bool validation_ = false;
    bool echo_ = true;
    bool pipelineStatistics_ = false;
    bool fragmentAtomics_ = false;
    bool float64_ = false;
    std::string name_;
    VkInstance instance_ = VK_NULL_HANDLE;
    VkDebugUtilsMessengerEXT messenger_ = VK_NULL_HANDLE;
    VkPhysicalDevice physical_ = VK_NULL_HANDLE;
    VkPhysicalDeviceProperties properties_{};
    VkPhysicalDeviceMemoryProperties memory_{};
    VkDevice device_ = VK_NULL_HANDLE;
    VkQueue queue_ = VK_NULL_HANDLE;
    std::uint32_t queueFamily_ = 0;
    VkCommandPool pool_ = VK_NULL_HANDLE;
    VkFence fence_ = VK_NULL_HANDLE;

    /// What the debug callback writes to (stable address for the messenger's pUserData).
    struct MessageSink {
        VulkanMessageLog* log;
        bool echo;
    };
    std::unique_ptr<MessageSink> sink_;
    static VKAPI_ATTR VkBool32 VKAPI_CALL
    onMessage(VkDebugUtilsMessageSeverityFlagBitsEXT severity, VkDebugUtilsMessageTypeFlagsEXT type,
              const VkDebugUtilsMessengerCallbackDataEXT* data, void* user);
    void destroy() noexcept;
};

/// A buffer with its own memory, persistently mapped when host-visible.
class VulkanBuffer {
  public:
    VulkanBuffer() = default;
    VulkanBuffer(VulkanDevice& device, VkDeviceSize size, VkBufferUsageFlags usage,
                 bool hostVisible);
    ~VulkanBuffer() { reset(); }
    VulkanBuffer(VulkanBuffer&& o) noexcept { *this = std::move(o); }
    VulkanBuffer& operator=(VulkanBuffer&& o) noexcept;
    VulkanBuffer(const VulkanBuffer&) = delete;
    VulkanBuffer& operator=(const VulkanBuffer&) = delete;

    void reset() noexcept;
    VkBuffer handle() const { return buffer_; }
    VkDeviceSize size() const { return size_; }
    void* mapped() const { return mapped_; }
    explicit operator bool() const { return buffer_ != VK_NULL_HANDLE; }

  private:
    VkDevice device_ = VK_NULL_HANDLE;
    VkBuffer buffer_ = VK_NULL_HANDLE;
    VkDeviceMemory memory_ = VK_NULL_HANDLE;
    VkDeviceSize size_ = 0;
    void* mapped_ = nullptr;
};

/// An optimally tiled 2D or 3D image with its own device memory and one view.
class VulkanImage {
  public:
    VulkanImage() = default;
    VulkanImage(VulkanDevice& device, VkImageType type, VkFormat format, VkExtent3D extent,
                VkImageUsageFlags usage, VkImageAspectFlags aspect);
    ~VulkanImage() { reset(); }
    VulkanImage(VulkanImage&& o) noexcept { *this = std::move(o); }
    VulkanImage& operator=(VulkanImage&& o) noexcept;
    VulkanImage(const VulkanImage&) = delete;
    VulkanImage& operator=(const VulkanImage&) = delete;

    void reset() noexcept;
    VkImage handle() const { return image_; }
    VkImageView view() const { return view_; }
    VkExtent3D extent() const { return extent_; }
    VkFormat format() const { return format_; }
    VkImageAspectFlags aspect() const { return aspect_; }
    explicit operator bool() const { return image_ != VK_NULL_HANDLE; }

  private:
    VkDevice device_ = VK_NULL_HANDLE;
    VkImage image_ = VK_NULL_HANDLE;
    VkImageView view_ = VK_NULL_HANDLE;
    VkDeviceMemory memory_ = VK_NULL_HANDLE;
    VkExtent3D extent_{0, 0, 0};
    VkFormat format_ = VK_FORMAT_UNDEFINED;
    VkImageAspectFlags aspect_ = 0;
};

/// The instance's physical devices; empty when there are none or the loader fails to list them.
std::vector<VkPhysicalDevice> physicalDevicesOf(VkInstance instance);

/// A pipeline barrier on one whole single-mip, single-layer image.
void imageBarrier(VkCommandBuffer cb, VkImage image, VkImageAspectFlags aspect, VkImageLayout from,
                  VkImageLayout to, VkPipelineStageFlags srcStage, VkAccessFlags srcAccess,
                  VkPipelineStageFlags dstStage, VkAccessFlags dstAccess);
/// A pipeline barrier on one whole buffer (no queue family transfer).
void bufferBarrier(VkCommandBuffer cb, VkBuffer buffer, VkPipelineStageFlags srcStage,
                   VkAccessFlags srcAccess, VkPipelineStageFlags dstStage, VkAccessFlags dstAccess);

} // namespace voxtier
