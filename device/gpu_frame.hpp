#pragma once
// One frame of GPU work, whatever tier records into it: what every Vulkan frame needs and no tier
// owns.
//  - The image planes: the rasteriser's attachments (colour as the kernel's packed RGBA8 in
//    R32_UINT, the entity id in R32_UINT, reversed-Z depth in D32_SFLOAT) and `planes`, the same
//    three planes as words of one storage buffer (colour, then id, then depth bits, width x
//    height each), where compute passes compose after the rasteriser by the depth/id rule
//    (the cell-rate resolve, the far pass).
//  - The command buffer, its fence, the named device timestamps of its passes
//    (device/pass_timer.hpp) and the staging ring its uploads go through
//    (device/staging_ring.hpp).
//  - The readback: the planes copied into host-cached memory (device/memory_policy.hpp,
//    Readback) and unpacked into an Image. Where that memory is device-local (lavapipe,
//    integrated GPUs) the passes compose straight in it and nothing is copied.
//
// Frames may be in flight together: a GpuFrames hands out `slots` frames in turn, each with its
// own command buffer, fence, timestamps and readback memory; beginning a frame waits for the
// frame that last used its slot. Every frame starts with a full barrier, so what the slots share
// (the attachments, the planes on a discrete GPU, the tiers' device-only buffers) is written by
// one frame only after the frame before has finished with it.
//
// Frame protocol (one thread):
//   GpuFrame& f = frames.begin(width, height);      // recording starts
//   ... tiers record: uploads (f.hostWrite / f.ring()), passes (f.timer()), the raster pass into
//       f.color()/f.id()/f.depth() then f.recordTargetsToPlanes(), or f.recordClearPlanes() ...
//   f.submitSoFar();                                 // optional: the device starts, recording
//   ... more passes ...                               // goes on
//   f.recordReadback(depthAndIds);                   // optional: only when someone reads it
//   f.submit();
//   f.wait();  Image img = f.read(depthAndIds);
#include "core/image.hpp"
#include "device/pass_timer.hpp"
#include "device/staging_ring.hpp"
#include "device/vulkan_device.hpp"

#include <cstdint>
#include <memory>
#include <vector>

namespace voxtier {

/// Host time of one frame's GPU half (ms), split the way the figures report it.
struct GpuFrameHostTimes {
    double waitMs = 0.0;     ///< blocked in wait() until the fence signalled
    double readbackMs = 0.0; ///< invalidate + unpack of the read-back planes into the Image
};

class GpuFrames;

class GpuFrame {
  public:
    static constexpr VkFormat kColorFormat = VK_FORMAT_R32_UINT; ///< the kernel's packed RGBA8
    static constexpr VkFormat kIdFormat = VK_FORMAT_R32_UINT;
    static constexpr VkFormat kDepthFormat = VK_FORMAT_D32_SFLOAT; ///< the kernel's float depth

    ~GpuFrame();
    GpuFrame(const GpuFrame&) = delete;
    GpuFrame& operator=(const GpuFrame&) = delete;

    VulkanDevice& device() const { return *device_; }
    /// Which of the GpuFrames' slots this frame uses (per-slot resources of the tiers).
    int slot() const { return slot_; }
    /// Increases with every frame begun.
    std::uint64_t serial() const { return serial_; }
    int width() const { return width_; }
    int height() const { return height_; }
    VkCommandBuffer commandBuffer() const { return cb_; }
    PassTimer& timer() { return *timer_; }
    StagingRing& ring();

    /// Where the host writes `bytes` for `dst` at `dstOffset`: straight into dst's mapping where
    /// its placement allows (HostWrite::Direct), else into the staging ring with the copy
    /// recorded now. Fill it before submit(). The caller records the ring's barrier
    /// (ring().recordBarrier) before the passes that read what was staged.
    void* hostWrite(VulkanBuffer& dst, VkDeviceSize dstOffset, VkDeviceSize bytes);
    /// hostWrite(dst, 0, bytes) filled from `data`, on every core: a tier's lists are megabytes
    /// at 100,000 sprites, and where the destination is write-combined device memory (resizable
    /// BAR) one core fills it at a fraction of the bus's rate (core/parallel_copy.hpp).
    void hostCopy(VulkanBuffer& dst, const void* data, VkDeviceSize bytes);

    /// Keeps `buffer` alive until this frame has executed (a buffer the frame still copies from
    /// while its owner has replaced it).
    void keepUntilDone(VulkanBuffer&& buffer);

    const VulkanImage& color() const;
    const VulkanImage& id() const;
    const VulkanImage& depth() const;
    /// The planes buffer (colour, id, depth words), where compute passes compose.
    VkBuffer planes() const;
    VkDeviceSize planeBytes() const { return VkDeviceSize(width_) * VkDeviceSize(height_) * 4; }
    /// The attachments after a render pass (left in TRANSFER_SRC_OPTIMAL) into the planes, with
    /// the barrier that makes them visible to compute shaders and transfers. The colour plane
    /// alone unless `allPlanes` (a later pass composes by depth and id, or they are read back).
    void recordTargetsToPlanes(bool allPlanes);
    /// The planes filled with what a render pass clears to (`clear` colour, no entity, depth 0:
    /// infinitely far), for a frame that rasterises nothing.
    void recordClearPlanes(std::uint32_t clear, bool allPlanes);
    /// Copies the planes into the slot's readback memory (colour alone unless `depthAndIds`).
    /// Without it the frame is drawn and timed but not read: read() returns an empty Image.
    void recordReadback(bool depthAndIds);

    /// Submits what is recorded so far, without the fence, and goes on recording into the
    /// slot's second command buffer (after a full barrier): the device starts on the first part
    /// while the host prepares the rest (a hybrid frame's far bakes while its near passes draw).
    /// At most once a frame; submit() then submits the rest with the fence. The frame's device
    /// time is then two passes of timer(), "frame" and "frame_rest" (the device may wait between).
    void submitSoFar();
    /// Ends recording and submits with the slot's fence.
    void submit();
    /// Blocks until the frame has executed (then timer().results() and read() are valid).
    void wait();
    /// The read-back planes as an Image (depth and ids empty unless `depthAndIds` and read back
    /// with them).
    Image read(bool depthAndIds);
    const GpuFrameHostTimes& hostTimes() const { return host_; }
    bool submitted() const { return submitted_; }

  private:
    friend class GpuFrames;
    /// Closes the open frame span, flushes the host's writes and submits the command buffer
    /// recorded so far with `fence` (reset first; VK_NULL_HANDLE: none).
    void submitRecorded(VkFence fence);
    explicit GpuFrame(GpuFrames& owner, int slot);

    GpuFrames* owner_;
    VulkanDevice* device_;
    int slot_ = 0;
    std::uint64_t serial_ = 0;
    int width_ = 0, height_ = 0;
    VkCommandBuffer cb_ = VK_NULL_HANDLE;
    /// The slot's other command buffer: what submitSoFar() goes on recording into (the two take
    /// turns: both are done once the slot's fence has signalled).
    VkCommandBuffer cbRest_ = VK_NULL_HANDLE;
    VkFence fence_ = VK_NULL_HANDLE;
    std::unique_ptr<PassTimer> timer_;
    /// Host-cached memory the planes are copied into (or, where device-local, composed in).
    VulkanBuffer readback_;
    bool recording_ = false, submitted_ = false, readBack_ = false, readBackAll_ = false;
    bool partSubmitted_ = false; ///< submitSoFar() ran this frame (its part has no fence)
    bool unread_ = false;        ///< submitted with a readback that read() has not copied out yet
    std::vector<VulkanBuffer*> directFlushes_; ///< direct writes to flush before submit
    std::vector<VulkanBuffer> keptAlive_;      ///< released once the frame has executed
    GpuFrameHostTimes host_;
};

class GpuFrames {
  public:
    explicit GpuFrames(VulkanDevice& device, int slots = 2);
    ~GpuFrames();
    GpuFrames(const GpuFrames&) = delete;
    GpuFrames& operator=(const GpuFrames&) = delete;

    /// Starts the next frame at width x height in the next slot whose frame has been read back
    /// (throws std::logic_error when every slot holds an unread frame): waits for the frame that
    /// last used its slot,
    /// (re)creates the targets at this size, and begins recording with the frame-start barrier
    /// and the timer's reset.
    GpuFrame& begin(int width, int height);
    int slots() const { return int(frames_.size()); }
    VulkanDevice& device() const { return device_; }
    /// The passes compose in the readback memory itself (it is device-local): no planes copy.
    bool composeInReadback() const { return composeInReadback_; }
    /// Waits for every frame in flight.
    void waitAll();

  private:
    friend class GpuFrame;
    void ensureTargets(int width, int height);

    VulkanDevice& device_;
    StagingRing ring_;
    std::vector<std::unique_ptr<GpuFrame>> frames_;
    std::uint64_t serial_ = 0;
    std::size_t nextSlot_ = 0; ///< where begin() looks first (slots are handed out in turn)
    bool composeInReadback_ = false;
    int width_ = 0, height_ = 0;
    VulkanImage color_, id_, depth_;
    VulkanBuffer planes_; ///< DeviceOnly, where the readback memory is not device-local
};

} // namespace voxtier
