#include "device/gpu_frame.hpp"

#include "core/parallel_copy.hpp"
#include "core/sprite_kernel.h"
#include "core/stopwatch.hpp"

#include <algorithm>
#include <chrono>
#include <cstring>
#include <span>
#include <stdexcept>
#include <utility>

namespace voxtier {

namespace {

using Clock = std::chrono::steady_clock;

/// The staging ring's first size: a frame of a few thousand sprites fits; it grows as needed.
constexpr VkDeviceSize kInitialRingBytes = VkDeviceSize(4) << 20;

/// Every stage and access: the frame-start barrier orders a frame after everything before it.
void fullBarrier(VkCommandBuffer cb) {
    VkMemoryBarrier b{VK_STRUCTURE_TYPE_MEMORY_BARRIER};
    b.srcAccessMask = VK_ACCESS_MEMORY_WRITE_BIT;
    b.dstAccessMask = VK_ACCESS_MEMORY_READ_BIT | VK_ACCESS_MEMORY_WRITE_BIT;
    vkCmdPipelineBarrier(cb, VK_PIPELINE_STAGE_ALL_COMMANDS_BIT, VK_PIPELINE_STAGE_ALL_COMMANDS_BIT,
                         0, 1, &b, 0, nullptr, 0, nullptr);
}

/// Starts recording into `cb` (idle: what it held has executed), after everything submitted
/// before it (fullBarrier): a frame's start, and the rest of a frame after submitSoFar.
void beginRecording(VkCommandBuffer cb) {
    VK_CHECK(vkResetCommandBuffer(cb, 0));
    VkCommandBufferBeginInfo bi{VK_STRUCTURE_TYPE_COMMAND_BUFFER_BEGIN_INFO};
    bi.flags = VK_COMMAND_BUFFER_USAGE_ONE_TIME_SUBMIT_BIT;
    VK_CHECK(vkBeginCommandBuffer(cb, &bi));
    fullBarrier(cb);
}

/// The planes of a width x height frame (colour, id, depth: one 32-bit word a pixel each), and
/// how their buffers are used (written by compute passes and copies, copied out).
VkDeviceSize planesBytesOf(int width, int height) {
    return 3 * VkDeviceSize(width) * VkDeviceSize(height) * 4;
}
constexpr VkBufferUsageFlags kPlanesUsage = VK_BUFFER_USAGE_STORAGE_BUFFER_BIT |
                                            VK_BUFFER_USAGE_TRANSFER_DST_BIT |
                                            VK_BUFFER_USAGE_TRANSFER_SRC_BIT;

} // namespace

// ---------------------------------------------------------------------------------------------
// GpuFrame

GpuFrame::GpuFrame(GpuFrames& owner, int slot)
    : owner_(&owner), device_(&owner.device()), slot_(slot) {
    cb_ = device_->allocateCommandBuffer();
    try {
        cbRest_ = device_->allocateCommandBuffer();
    } catch (...) {
        device_->freeCommandBuffer(cb_);
        throw;
    }
    VkFenceCreateInfo fci{VK_STRUCTURE_TYPE_FENCE_CREATE_INFO};
    fci.flags = VK_FENCE_CREATE_SIGNALED_BIT; // a slot never used is free
    const VkResult r = vkCreateFence(device_->device(), &fci, nullptr, &fence_);
    if (r != VK_SUCCESS) {
        device_->freeCommandBuffer(cb_);
        device_->freeCommandBuffer(cbRest_);
        VK_CHECK(r);
    }
    timer_ = std::make_unique<PassTimer>(*device_);
}

GpuFrame::~GpuFrame() {
    // A part submitted without the fence, of a frame never submitted whole (an exception while
    // recording the rest), may still run.
    if (recording_ && partSubmitted_) vkQueueWaitIdle(device_->queue());
    if (fence_) {
        vkWaitForFences(device_->device(), 1, &fence_, VK_TRUE, UINT64_MAX);
        vkDestroyFence(device_->device(), fence_, nullptr);
    }
    device_->freeCommandBuffer(cb_);
    device_->freeCommandBuffer(cbRest_);
}

StagingRing& GpuFrame::ring() {
    return owner_->ring_;
}

const VulkanImage& GpuFrame::color() const {
    return owner_->color_;
}
const VulkanImage& GpuFrame::id() const {
    return owner_->id_;
}
const VulkanImage& GpuFrame::depth() const {
    return owner_->depth_;
}

VkBuffer GpuFrame::planes() const {
    return owner_->composeInReadback_ ? readback_.handle() : owner_->planes_.handle();
}

void* GpuFrame::hostWrite(VulkanBuffer& dst, VkDeviceSize dstOffset, VkDeviceSize bytes) {
    if (bytes == 0) return nullptr;
    if (dstOffset > dst.size() || bytes > dst.size() - dstOffset)
        throw std::logic_error("GpuFrame::hostWrite past the end of the buffer");
    switch (dst.placement().hostWrite) {
    case HostWrite::Direct:
        if (dst.placement().flushAfterWrite) directFlushes_.push_back(&dst);
        return static_cast<std::uint8_t*>(dst.mapped()) + dstOffset;
    case HostWrite::Staged:
        return owner_->ring_.uploadInPlace(cb_, dst.handle(), dstOffset, bytes);
    case HostWrite::None:
        break;
    }
    throw std::logic_error("GpuFrame::hostWrite: the host does not write this buffer");
}

void GpuFrame::hostCopy(VulkanBuffer& dst, const void* data, VkDeviceSize bytes) {
    if (bytes) copyInParallel({{hostWrite(dst, 0, bytes), data, std::size_t(bytes)}});
}

void GpuFrame::keepUntilDone(VulkanBuffer&& buffer) {
    keptAlive_.push_back(std::move(buffer));
}

void GpuFrame::recordTargetsToPlanes(bool allPlanes) {
    const VulkanImage* images[3] = {&color(), &id(), &depth()};
    for (int i = 0; i < (allPlanes ? 3 : 1); ++i) {
        VkBufferImageCopy region{};
        region.bufferOffset = planeBytes() * VkDeviceSize(i);
        region.imageSubresource = {images[i]->aspect(), 0, 0, 1};
        region.imageExtent = {std::uint32_t(width_), std::uint32_t(height_), 1};
        vkCmdCopyImageToBuffer(cb_, images[i]->handle(), VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL,
                               planes(), 1, &region);
    }
    bufferBarrier(cb_, planes(), VK_PIPELINE_STAGE_TRANSFER_BIT, VK_ACCESS_TRANSFER_WRITE_BIT,
                  VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT | VK_PIPELINE_STAGE_TRANSFER_BIT,
                  VK_ACCESS_SHADER_READ_BIT | VK_ACCESS_SHADER_WRITE_BIT |
                      VK_ACCESS_TRANSFER_READ_BIT);
}

void GpuFrame::recordClearPlanes(std::uint32_t clear, bool allPlanes) {
    const VkDeviceSize plane = planeBytes();
    vkCmdFillBuffer(cb_, planes(), 0, plane, clear);
    if (allPlanes) {
        vkCmdFillBuffer(cb_, planes(), plane, plane, kernel::VT_NO_ENTITY);
        vkCmdFillBuffer(cb_, planes(), 2 * plane, plane, 0u); // depth 0.0f: nothing drawn
    }
    bufferBarrier(cb_, planes(), VK_PIPELINE_STAGE_TRANSFER_BIT, VK_ACCESS_TRANSFER_WRITE_BIT,
                  VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT | VK_PIPELINE_STAGE_TRANSFER_BIT,
                  VK_ACCESS_SHADER_READ_BIT | VK_ACCESS_SHADER_WRITE_BIT |
                      VK_ACCESS_TRANSFER_READ_BIT);
}

void GpuFrame::recordReadback(bool depthAndIds) {
    readBack_ = true;
    readBackAll_ = depthAndIds;
    timer_->begin(cb_, "readback_copy");
    if (!owner_->composeInReadback_) {
        const VkBufferCopy copy{0, 0, planeBytes() * (depthAndIds ? 3 : 1)};
        vkCmdCopyBuffer(cb_, planes(), readback_.handle(), 1, &copy);
    }
    timer_->end(cb_);
    bufferBarrier(cb_, readback_.handle(),
                  VK_PIPELINE_STAGE_TRANSFER_BIT | VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT,
                  VK_ACCESS_TRANSFER_WRITE_BIT | VK_ACCESS_SHADER_WRITE_BIT,
                  VK_PIPELINE_STAGE_HOST_BIT, VK_ACCESS_HOST_READ_BIT);
}

void GpuFrame::submitRecorded(VkFence fence) {
    timer_->end(cb_); // "frame", or "frame_rest" after submitSoFar
    owner_->ring_.flushPending();
    for (VulkanBuffer* b : directFlushes_) b->flush();
    directFlushes_.clear();
    VK_CHECK(vkEndCommandBuffer(cb_));
    VkSubmitInfo si{VK_STRUCTURE_TYPE_SUBMIT_INFO};
    si.commandBufferCount = 1;
    si.pCommandBuffers = &cb_;
    if (fence) VK_CHECK(vkResetFences(device_->device(), 1, &fence));
    VK_CHECK(vkQueueSubmit(device_->queue(), 1, &si, fence));
}

void GpuFrame::submitSoFar() {
    if (!recording_) throw std::logic_error("GpuFrame::submitSoFar: not recording");
    if (partSubmitted_) throw std::logic_error("GpuFrame::submitSoFar: once a frame");
    // The frame's device time in two spans, "frame" and "frame_rest": the device may wait for the
    // rest between them, which is no work of the frame's. No fence: one queue runs the parts in
    // order, and the rest's fence signals after both.
    submitRecorded(VK_NULL_HANDLE);
    partSubmitted_ = true;
    std::swap(cb_, cbRest_);
    // The slot's last frame, which used the other buffer if any did, has finished (begin() waited);
    // what the first part wrote is available and visible to the rest (beginRecording's barrier).
    beginRecording(cb_);
    timer_->begin(cb_, "frame_rest");
}

void GpuFrame::submit() {
    if (!recording_) throw std::logic_error("GpuFrame::submit: not recording");
    submitRecorded(fence_);
    recording_ = false;
    submitted_ = true;
    unread_ = readBack_; // its slot is not handed out again until read() has copied it out
}

void GpuFrame::wait() {
    if (!submitted_) return;
    const auto t0 = Clock::now();
    VK_CHECK(vkWaitForFences(device_->device(), 1, &fence_, VK_TRUE, UINT64_MAX));
    host_.waitMs = msSince(t0);
    submitted_ = false;
    keptAlive_.clear();
    // One queue executes frames in order: every earlier frame has finished too.
    owner_->ring_.retire(serial_);
}

Image GpuFrame::read(bool depthAndIds) {
    wait();
    Image img;
    if (!readBack_) return img;
    const auto t0 = Clock::now();
    const bool all = depthAndIds && readBackAll_;
    readback_.invalidateForRead(0, planeBytes() * (all ? 3 : 1));
    img.width = width_;
    img.height = height_;
    const std::size_t count = img.pixelCount();
    // The planes' resize() writes nothing (Plane's allocator leaves new words uninitialised), so
    // each byte is written once, by the copy, on every core: one core copied the 6 MB of a
    // 960x540 frame in 0.6-0.9 ms on the H200's host, most of an empty frame.
    const auto* base = static_cast<const std::uint8_t*>(readback_.mapped());
    img.color.resize(count);
    if (all) img.id.resize(count), img.depth.resize(count);
    const std::size_t bytes = std::size_t(planeBytes());
    const CopyPiece planes[] = {{img.color.data(), base, bytes},
                                {img.id.data(), base + planeBytes(), bytes},
                                {img.depth.data(), base + 2 * planeBytes(), bytes}};
    copyInParallel(std::span(planes, all ? 3 : 1));
    host_.readbackMs = msSince(t0);
    unread_ = false;
    return img;
}

// ---------------------------------------------------------------------------------------------
// GpuFrames

GpuFrames::GpuFrames(VulkanDevice& device, int slots)
    : device_(device), ring_(device, kInitialRingBytes) {
    // Composing in the readback memory saves a copy of the planes wherever that memory is the
    // device's own (its placement is device-local): lavapipe, integrated GPUs.
    const MemoryPlacement readback = device.placementFor(BufferClass::Readback, ~0u);
    composeInReadback_ = (readback.flags & VK_MEMORY_PROPERTY_DEVICE_LOCAL_BIT) != 0;
    for (int s = 0; s < std::max(1, slots); ++s)
        frames_.push_back(std::unique_ptr<GpuFrame>(new GpuFrame(*this, s)));
}

GpuFrames::~GpuFrames() {
    waitAll();
}

void GpuFrames::waitAll() {
    for (auto& f : frames_) f->wait();
}

void GpuFrames::ensureTargets(int w, int h) {
    if (w == width_ && h == height_ && color_) return;
    // The targets are shared by the slots: no frame may still be using the old ones.
    waitAll();
    const VkExtent3D extent{std::uint32_t(w), std::uint32_t(h), 1};
    const VkImageUsageFlags colorUsage =
        VK_IMAGE_USAGE_COLOR_ATTACHMENT_BIT | VK_IMAGE_USAGE_TRANSFER_SRC_BIT;
    color_ = VulkanImage(device_, VK_IMAGE_TYPE_2D, GpuFrame::kColorFormat, extent, colorUsage,
                         VK_IMAGE_ASPECT_COLOR_BIT);
    id_ = VulkanImage(device_, VK_IMAGE_TYPE_2D, GpuFrame::kIdFormat, extent, colorUsage,
                      VK_IMAGE_ASPECT_COLOR_BIT);
    depth_ =
        VulkanImage(device_, VK_IMAGE_TYPE_2D, GpuFrame::kDepthFormat, extent,
                    VK_IMAGE_USAGE_DEPTH_STENCIL_ATTACHMENT_BIT | VK_IMAGE_USAGE_TRANSFER_SRC_BIT,
                    VK_IMAGE_ASPECT_DEPTH_BIT);
    planes_ = composeInReadback_ ? VulkanBuffer()
                                 : VulkanBuffer(device_, planesBytesOf(w, h), kPlanesUsage,
                                                BufferClass::DeviceOnly);
    width_ = w;
    height_ = h;
}

GpuFrame& GpuFrames::begin(int width, int height) {
    // The next slot in turn whose frame has been read back: a frame submitted and not yet read
    // keeps its readback memory (where, on some devices, its passes composed) until read() copies
    // it out, whatever frames are begun meanwhile.
    GpuFrame* next = nullptr;
    for (std::size_t k = 0; k < frames_.size() && !next; ++k) {
        GpuFrame& c = *frames_[(nextSlot_ + k) % frames_.size()];
        if (!c.unread_) next = &c;
    }
    if (!next)
        throw std::logic_error("GpuFrames::begin: all " + std::to_string(frames_.size()) +
                               " frames are in flight and unread; read one back first");
    GpuFrame& f = *next;
    nextSlot_ = (std::size_t(f.slot_) + 1) % frames_.size();
    if (f.recording_) {
        // Begun and never submitted (an exception while recording): drop it, and its staging
        // space once nothing earlier is in flight either (its part submitted without the fence,
        // if any, included).
        f.recording_ = false; // vkResetCommandBuffer below resets it from the recording state
        waitAll();
        if (f.partSubmitted_) VK_CHECK(vkQueueWaitIdle(device_.queue()));
        ring_.retire(f.serial_);
    }
    f.partSubmitted_ = false;
    f.wait(); // the slot's previous frame
    f.keptAlive_.clear();
    ensureTargets(width, height);
    // The slot's readback memory, sized for the largest frame it has held (per slot: another
    // slot's may still hold a frame not yet read).
    const VkDeviceSize planesBytes = planesBytesOf(width, height);
    if (f.readback_.size() < planesBytes)
        f.readback_ = VulkanBuffer(device_, planesBytes, kPlanesUsage, BufferClass::Readback);
    f.serial_ = ++serial_;
    f.width_ = width;
    f.height_ = height;
    f.readBack_ = f.readBackAll_ = false;
    f.host_ = {};
    beginRecording(f.cb_);
    f.recording_ = true;
    ring_.beginFrame(f.serial_);
    f.timer_->reset(f.cb_);
    f.timer_->begin(f.cb_, "frame"); // the whole frame, closed by submit()
    return f;
}

} // namespace voxtier
