#pragma once
// Where each kind of buffer lives, decided in one place (issue 35, docs/decisions/
// gpu-memory-placement.md). A pure function of the device's memory-type table, so it is
// unit-tested against the tables of real devices (tests/data/vulkan_memory/) without them.
//
// The contract, per buffer class:
// - ShaderRead (host-written, read by shaders every frame or on change): device-local memory.
//   The host writes it directly when the device offers device-local host-visible memory on a
//   heap as large as its main device-local heap (resizable BAR, integrated GPUs and unified
//   memory, lavapipe); otherwise the buffer is device-local only and written through a staging
//   copy (HostWrite::Staged). The small (~256 MiB) BAR window of a discrete GPU without
//   resizable BAR is never used: it is too small to hold everything and CPU writes to it cross
//   PCIe uncached anyway.
// - DeviceOnly (written and read by the device): device-local memory, preferring a type the
//   host cannot see (it does not use up a BAR window).
// - Staging (host-written copy source): host-visible memory, preferring system memory that is
//   coherent and write-combined (not host-cached: the host only writes it sequentially).
// - Readback (device-written, host-read): host-visible and host-cached memory, so reading it
//   runs at CPU cache speed instead of uncached reads across PCIe; where the cached type is
//   not coherent the reader invalidates before reading (MemoryPlacement::invalidateBeforeRead).
//
// Memory types the policy never picks for a buffer: AMD's device-coherent/uncached types (they
// need the deviceCoherentMemory feature), protected and lazily-allocated types, and types on an
// empty heap.
#include <vulkan/vulkan.h>

#include <cstdint>
#include <optional>
#include <string>

namespace voxtier {

enum class BufferClass : std::uint8_t { ShaderRead, DeviceOnly, Staging, Readback };
inline constexpr BufferClass kAllBufferClasses[] = {
    BufferClass::ShaderRead, BufferClass::DeviceOnly, BufferClass::Staging, BufferClass::Readback};
const char* bufferClassName(BufferClass c); ///< "ShaderRead", "DeviceOnly", ...

/// How the host puts data into a buffer of that placement.
enum class HostWrite : std::uint8_t {
    None,   ///< the host does not write it (DeviceOnly, Readback)
    Direct, ///< memcpy into the persistent mapping (then flush when not coherent)
    Staged, ///< through a staging buffer and a copy recorded into the frame's command buffer
};
const char* hostWriteName(HostWrite w); ///< "none", "direct", "staged"

struct MemoryPlacement {
    std::uint32_t typeIndex = 0;
    VkMemoryPropertyFlags flags = 0;
    std::uint32_t heapIndex = 0;
    VkDeviceSize heapSize = 0;
    HostWrite hostWrite = HostWrite::None;
    /// The memory is host-visible: the buffer is mapped persistently for its lifetime.
    bool mapped = false;
    /// Mapped but not host-coherent: host writes need vkFlushMappedMemoryRanges.
    bool flushAfterWrite = false;
    /// Mapped but not host-coherent: device writes need vkInvalidateMappedMemoryRanges before
    /// the host reads them (Readback on such a device).
    bool invalidateBeforeRead = false;
};

struct PlacementOptions {
    /// Test and diagnosis override: ShaderRead buffers take the staged path even where direct
    /// writes are possible (so lavapipe, whose only memory type is device-local and host-visible,
    /// can exercise the staging ring). Also set by VOXTIER_FORCE_STAGING=1 (VulkanDevice).
    bool forceStaging = false;
};

/// The placement of a buffer of class `c` whose memory requirements allow the types in
/// `typeBits` (VkMemoryRequirements::memoryTypeBits), or nullopt when none of the allowed types
/// can serve the class at all (e.g. Staging with no host-visible type among typeBits).
std::optional<MemoryPlacement> placeBuffer(const VkPhysicalDeviceMemoryProperties& memory,
                                           std::uint32_t typeBits, BufferClass c,
                                           const PlacementOptions& options = {});

/// True when the device offers device-local, host-visible memory on a heap at least half the size
/// of its largest device-local heap (resizable BAR, integrated GPU, CPU implementation).
bool hasLargeHostVisibleDeviceMemory(const VkPhysicalDeviceMemoryProperties& memory,
                                     std::uint32_t typeBits = ~0u);

/// "DEVICE_LOCAL|HOST_VISIBLE|HOST_COHERENT" (vulkaninfo's names without MEMORY_PROPERTY_ and
/// _BIT), "NONE" for 0.
std::string memoryPropertyNames(VkMemoryPropertyFlags flags);
/// One line for a report: "type 4 (DEVICE_LOCAL|HOST_VISIBLE|HOST_COHERENT), heap 0 of 15.92 GiB,
/// host writes: direct".
std::string describePlacement(const MemoryPlacement& p);

} // namespace voxtier
