#pragma once
// A headless Vulkan 1.2 device: instance, physical-device choice (a GPU if there is one, else
// Mesa lavapipe on the CPU), one graphics queue, optional validation with every message
// recorded, and the few RAII resource wrappers the near renderer needs. No window, no
// swapchain. Not thread-safe: one thread drives a device.
//
// Buffers are placed by class (device/memory_policy.hpp): VulkanBuffer(device, size, usage,
// BufferClass) asks the device's policy where the buffer lives and how the host writes it.
#include "device/memory_policy.hpp"
#include "device/vulkan_check.hpp"
#include "device/vulkan_options.hpp"

#include <cstddef>
#include <cstdint>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <vector>

namespace voxtier {

class VulkanDevice {
  public:
    /// Throws VulkanError(noVulkanDeviceMessage(), device/icd_diagnosis.hpp) when no Vulkan 1.2
    /// device with a graphics queue exists, and VulkanError when validation is asked for but the
    /// layer is missing.
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
    /// For images; buffers go through placementFor().
    std::uint32_t memoryType(std::uint32_t typeBits, VkMemoryPropertyFlags required) const;
    const VkPhysicalDeviceMemoryProperties& memoryProperties() const { return memory_; }
    /// The policy's placement (device/memory_policy.hpp) of a buffer of class `c` whose memory
    /// requirements allow `typeBits`, with this device's options (forced staging). Throws
    /// VulkanError when no allowed type can serve the class.
    MemoryPlacement placementFor(BufferClass c, std::uint32_t typeBits) const;
    /// ShaderRead buffers are staged even where the host could write them directly (options or
    /// VOXTIER_FORCE_STAGING=1): the staging path, testable on lavapipe.
    bool forcesStaging() const { return placementOptions_.forceStaging; }
    /// VkPhysicalDeviceLimits::nonCoherentAtomSize: flush/invalidate ranges are rounded to it.
    VkDeviceSize nonCoherentAtomSize() const { return properties_.limits.nonCoherentAtomSize; }
    /// Valid bits of a timestamp written on the device's queue; 0 when the queue has no
    /// timestamps (device/pass_timer.hpp reports no times then).
    std::uint32_t timestampValidBits() const { return timestampValidBits_; }
    /// Nanoseconds per timestamp tick (VkPhysicalDeviceLimits::timestampPeriod).
    float timestampPeriod() const { return properties_.limits.timestampPeriod; }

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
    std::uint32_t timestampValidBits_ = 0;
    PlacementOptions placementOptions_;
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
    // The constructor's steps, in order; each throws VulkanError, and the constructor destroys
    // what the earlier ones made.
    void createInstance(const VulkanDeviceOptions& options);
    void pickPhysicalDevice();
    void createLogicalDevice();
    void destroy() noexcept;
};

/// A buffer with its own memory, placed by class (device/memory_policy.hpp) and persistently
/// mapped when the placement is host-visible for the host's use (placement().mapped).
///
/// Usage flags the class needs are added to `usage`: TRANSFER_DST for a staged ShaderRead buffer
/// and for Readback, TRANSFER_SRC for Staging.
///
/// Host access contract:
/// - write(): only when placement().hostWrite == Direct (ShaderRead on a device with large
///   host-visible device memory, Staging). It copies into the mapping and flushes when the memory
///   is not coherent. Host writes are visible to commands submitted afterwards (vkQueueSubmit
///   orders them); the caller must not write a region the device may still be reading (keep one
///   buffer per frame in flight, or write after that frame's fence).
/// - A ShaderRead buffer with hostWrite == Staged is filled through StagingRing::upload
///   (device/staging_ring.hpp), or uploadToBuffer, which picks the path by itself.
/// - Readback: after the fence of the frame that wrote it, call invalidateForRead() (a no-op on
///   coherent memory) and read mapped().
class VulkanBuffer {
  public:
    VulkanBuffer() = default;
    VulkanBuffer(VulkanDevice& device, VkDeviceSize size, VkBufferUsageFlags usage,
                 BufferClass bufferClass);
    /// The placement before the policy, kept while volumetric/ and impostor_cache/ move to the
    /// class-based constructor: hostVisible picks the first HOST_VISIBLE|HOST_COHERENT type
    /// (mapped), otherwise the first DEVICE_LOCAL one. placement() reports what it got, with
    /// hostWrite Direct for the host-visible case.
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
    /// The persistent mapping, or nullptr when the placement is not mapped.
    void* mapped() const { return mapped_; }
    const MemoryPlacement& placement() const { return placement_; }
    explicit operator bool() const { return buffer_ != VK_NULL_HANDLE; }

    /// Copies `bytes` to `offset` in the mapping and flushes the range when not coherent.
    /// Throws VulkanError when the buffer is not host-writable (placement().hostWrite != Direct)
    /// or the range does not fit.
    void write(VkDeviceSize offset, const void* data, VkDeviceSize bytes);
    /// Flushes host writes to [offset, offset+bytes) when the memory is not coherent.
    void flush(VkDeviceSize offset = 0, VkDeviceSize bytes = VK_WHOLE_SIZE);
    /// Makes device writes to [offset, offset+bytes) visible to the host when the memory is not
    /// coherent. Call after the fence, before reading mapped().
    void invalidateForRead(VkDeviceSize offset = 0, VkDeviceSize bytes = VK_WHOLE_SIZE);

  private:
    /// With a class: the policy's placement; without: the legacy hostVisible choice.
    void create(VulkanDevice& device, VkDeviceSize size, VkBufferUsageFlags usage,
                std::optional<BufferClass> bufferClass, bool hostVisible);
    /// [offset, offset+bytes) widened to nonCoherentAtomSize (clamped to the allocation).
    VkMappedMemoryRange atomRange(VkDeviceSize offset, VkDeviceSize bytes) const;

    VkDevice device_ = VK_NULL_HANDLE;
    VkBuffer buffer_ = VK_NULL_HANDLE;
    VkDeviceMemory memory_ = VK_NULL_HANDLE;
    VkDeviceSize size_ = 0;
    VkDeviceSize allocationSize_ = 0;
    VkDeviceSize atom_ = 1;
    void* mapped_ = nullptr;
    MemoryPlacement placement_{};
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

/// A pass's layouts: a descriptor set layout of `bindings`, then a pipeline layout of that one set
/// with `pushBytes` of push constants seen by compute stages alone (lavapipe 22.3 crashes when
/// one range covers compute and graphics stages). Each is stored as soon as it exists, for the
/// caller to destroy, even when the second throws (VulkanError).
void createPassLayouts(VkDevice device, std::span<const VkDescriptorSetLayoutBinding> bindings,
                       std::uint32_t pushBytes, VkDescriptorSetLayout& setLayout,
                       VkPipelineLayout& pipelineLayout);
/// A shader module of SPIR-V `code`; the caller destroys it.
VkShaderModule createShaderModule(VkDevice device, std::span<const std::uint32_t> code);
/// A compute pipeline of SPIR-V `code` (entry point "main") with `layout`, its specialization
/// constant k (constant_id = k) set to `specialization[k]`; its module is gone by the time it
/// returns. Throws VulkanError.
VkPipeline createComputePipeline(VkDevice device, VkPipelineLayout layout,
                                 std::span<const std::uint32_t> code,
                                 std::span<const std::uint32_t> specialization = {});

} // namespace voxtier
