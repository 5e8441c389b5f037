#pragma once
// Uploads into device-local buffers the host cannot write directly (ShaderRead buffers on a
// discrete GPU without resizable BAR, device/memory_policy.hpp): a host-visible ring buffer
// whose space is handed out per frame and reclaimed once that frame's fence has signalled, and
// copies recorded into the frame's own command buffer (no extra submit, no wait).
//
// Frame protocol (one thread):
//   ring.beginFrame(k);                       // k strictly increasing
//   ring.upload(cb, dst, offset, data, n);    // any number; the copies are recorded into cb
//   ring.recordBarrier(cb, stage, access);    // once, before the commands that read dst
//   ... submit cb with the frame's fence ...
//   ring.retire(k);                           // after that fence: frame k's space is free again
// Frames may overlap (k+1 begun before k retired): each keeps its space until retired.
//
// The ring never stalls and never fails for space: when a frame's uploads do not fit beside the
// frames still in flight, it switches to a buffer twice as large (or as large as needed) and
// keeps the old one alive until every frame that used it is retired.
#include "device/vulkan_device.hpp"

#include <cstdint>
#include <deque>
#include <list>
#include <span>
#include <vector>

namespace voxtier {

/// One piece of StagingRing::uploadAll: `bytes` from `data` to `dstOffset` of the destination.
struct StagedPiece {
    const void* data = nullptr;
    VkDeviceSize bytes = 0;
    VkDeviceSize dstOffset = 0;
};

class StagingRing {
  public:
    /// A ring of `capacity` bytes of Staging-class memory (host-visible, coherent where the
    /// device has it).
    StagingRing(VulkanDevice& device, VkDeviceSize capacity);

    /// Starts frame `frame`; ids must increase. The previous frame's space stays in use until
    /// it is retired.
    void beginFrame(std::uint64_t frame);
    /// Copies `bytes` from `data` into the ring and records vkCmdCopyBuffer from the ring to
    /// `dst` at `dstOffset` into `cb` (which must be recording, outside a render pass). `dst`
    /// needs VK_BUFFER_USAGE_TRANSFER_DST_BIT (ShaderRead and Readback buffers have it). Zero
    /// bytes records nothing.
    void upload(VkCommandBuffer cb, VkBuffer dst, VkDeviceSize dstOffset, const void* data,
                VkDeviceSize bytes);
    /// upload() of every piece into the same `dst`: their bytes side by side in the ring and one
    /// vkCmdCopyBuffer of as many regions recorded into `cb` (the far pass's first frames of the
    /// 2,000-tank army under the error budget upload ~500 snapshots of ~2 KB a frame: one command,
    /// not one each). Pieces of zero bytes are skipped; none at all records nothing.
    void uploadAll(VkCommandBuffer cb, VkBuffer dst, std::span<const StagedPiece> pieces);
    /// upload() without a source: returns where to write the `bytes` (filled by the caller before
    /// the frame is submitted, then flushPending()), so large arrays are written once, straight
    /// into the ring. The copy to `dst` is recorded into `cb` now.
    void* uploadInPlace(VkCommandBuffer cb, VkBuffer dst, VkDeviceSize dstOffset,
                        VkDeviceSize bytes);
    /// Flushes what uploadInPlace handed out this frame, where the ring's memory is not coherent.
    void flushPending();
    /// Records one memory barrier from this frame's copies (transfer writes) to `dstStage` /
    /// `dstAccess`; records nothing when the frame uploaded nothing.
    void recordBarrier(VkCommandBuffer cb, VkPipelineStageFlags dstStage, VkAccessFlags dstAccess);
    /// Frames up to and including `frame` have completed on the device: their space, and any
    /// outgrown buffer only they used, are released.
    void retire(std::uint64_t frame);

    VkDeviceSize capacity() const { return buffer_.size(); }
    /// Bytes held by frames not yet retired (including the current one), wrap-around padding
    /// included.
    VkDeviceSize bytesInUse() const { return used_; }
    /// Bytes uploaded in the current frame (payload only).
    VkDeviceSize bytesThisFrame() const { return uploadedThisFrame_; }
    /// Copies recorded in the current frame.
    std::uint32_t copiesThisFrame() const { return copiesThisFrame_; }
    /// How many times the ring has grown (0 when the initial capacity sufficed).
    std::uint32_t growths() const { return growths_; }
    const VulkanBuffer& buffer() const { return buffer_; }

  private:
    struct Region {
        std::uint64_t frame;
        VkDeviceSize start; ///< offset where the frame's space begins
        VkDeviceSize bytes; ///< payload plus padding, contiguous from start modulo capacity
    };
    struct Outgrown {
        VulkanBuffer buffer;
        std::uint64_t lastFrame; ///< released once this frame is retired
    };
    /// Space for `bytes` in this frame's region (growing the ring if need be), and the copy from
    /// it to `dst` recorded into `cb`; returns the space's offset in buffer_.
    VkDeviceSize reserve(VkCommandBuffer cb, VkBuffer dst, VkDeviceSize dstOffset,
                         VkDeviceSize bytes);
    /// Space for `bytes` in this frame's region, growing the ring if need be; its offset.
    VkDeviceSize space(VkDeviceSize bytes);
    /// Offset of `bytes` of free space, or false when it does not fit beside frames in flight.
    bool allocate(VkDeviceSize bytes, VkDeviceSize& offset);
    void grow(VkDeviceSize atLeast);

    VulkanDevice* device_;
    VulkanBuffer buffer_;
    std::list<Outgrown> outgrown_;
    std::deque<Region> regions_; ///< oldest first; the back one is the current frame's
    VkDeviceSize head_ = 0;      ///< next free offset
    VkDeviceSize used_ = 0;
    bool frameOpen_ = false;
    /// What uploadInPlace handed out this frame on non-coherent memory, to flush before submit
    /// (the buffer may be an outgrown one by then: outgrown_ is a list, so it does not move).
    struct PendingFlush {
        VulkanBuffer* buffer;
        VkDeviceSize offset, bytes;
    };
    std::vector<PendingFlush> pendingFlushes_;
    std::vector<VkBufferCopy> regionsOfAll_; ///< uploadAll's, kept between calls
    VkDeviceSize uploadedThisFrame_ = 0;
    std::uint32_t copiesThisFrame_ = 0;
    std::uint32_t growths_ = 0;
};

/// Writes `bytes` into `dst` at `dstOffset` by the path its placement calls for: a memcpy into
/// the mapping (HostWrite::Direct, nothing recorded) or the ring (HostWrite::Staged, a copy
/// recorded into `cb`). Returns the path taken. Throws VulkanError for a buffer the host does not
/// write (HostWrite::None).
HostWrite uploadToBuffer(StagingRing& ring, VkCommandBuffer cb, VulkanBuffer& dst,
                         VkDeviceSize dstOffset, const void* data, VkDeviceSize bytes);

} // namespace voxtier
