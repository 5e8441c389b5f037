#include "device/staging_ring.hpp"

#include <algorithm>
#include <stdexcept>

namespace voxtier {

namespace {

/// Uploads start on 16-byte boundaries: vkCmdCopyBuffer needs none, but the host's memcpy into
/// write-combined memory is fastest on aligned lines.
constexpr VkDeviceSize kAlign = 16;

VkDeviceSize alignUp(VkDeviceSize v, VkDeviceSize a) {
    return (v + a - 1) / a * a;
}

} // namespace

StagingRing::StagingRing(VulkanDevice& device, VkDeviceSize capacity)
    : device_(&device),
      buffer_(device, std::max<VkDeviceSize>(capacity, kAlign), 0, BufferClass::Staging) {}

void StagingRing::beginFrame(std::uint64_t frame) {
    if (!regions_.empty() && frame <= regions_.back().frame)
        throw std::logic_error("StagingRing::beginFrame: frame ids must increase");
    regions_.push_back(Region{frame, head_, 0});
    frameOpen_ = true;
    uploadedThisFrame_ = 0;
    copiesThisFrame_ = 0;
}

bool StagingRing::allocate(VkDeviceSize bytes, VkDeviceSize& offset) {
    const VkDeviceSize cap = buffer_.size();
    Region& current = regions_.back();
    if (bytes > cap) return false;
    VkDeviceSize consumed = 0;
    if (used_ == 0) {
        // Nothing in flight: start at the beginning instead of wrapping later.
        head_ = 0;
        current.start = 0;
        offset = 0;
        consumed = bytes;
    } else {
        // Frames' spaces are contiguous in allocation order: the oldest live byte is the start
        // of the first region that holds any.
        VkDeviceSize tail = head_;
        for (const Region& r : regions_)
            if (r.bytes > 0) {
                tail = r.start;
                break;
            }
        if (tail == head_) return false; // full
        const VkDeviceSize at = alignUp(head_, kAlign);
        if (tail < head_) {
            // Live data in [tail, head): free space is [head, cap), then [0, tail).
            if (at + bytes <= cap) {
                offset = at;
                consumed = at - head_ + bytes;
            } else if (bytes <= tail) {
                offset = 0;
                consumed = (cap - head_) + bytes;
            } else {
                return false;
            }
        } else {
            // Wrapped: live data in [tail, cap) and [0, head); free space is [head, tail).
            if (at + bytes > tail) return false;
            offset = at;
            consumed = at - head_ + bytes;
        }
    }
    head_ = offset + bytes;
    used_ += consumed;
    current.bytes += consumed;
    return true;
}

void StagingRing::grow(VkDeviceSize atLeast) {
    const std::uint64_t frame = regions_.back().frame;
    const VkDeviceSize capacity = std::max(2 * buffer_.size(), alignUp(atLeast, kAlign) * 2);
    // The old buffer holds this frame's earlier uploads and those of frames still in flight: it
    // lives until all of them are retired. The new one starts empty.
    outgrown_.push_back(Outgrown{std::move(buffer_), frame});
    for (PendingFlush& p : pendingFlushes_)
        if (p.buffer == &buffer_) p.buffer = &outgrown_.back().buffer;
    buffer_ = VulkanBuffer(*device_, capacity, 0, BufferClass::Staging);
    regions_.clear();
    regions_.push_back(Region{frame, 0, 0});
    head_ = 0;
    used_ = 0;
    ++growths_;
}

VkDeviceSize StagingRing::space(VkDeviceSize bytes) {
    if (!frameOpen_) throw std::logic_error("StagingRing::upload outside beginFrame/retire");
    VkDeviceSize offset = 0;
    if (!allocate(bytes, offset)) {
        grow(bytes);
        if (!allocate(bytes, offset))
            throw std::logic_error("StagingRing: no space after growing"); // cannot happen
    }
    return offset;
}

VkDeviceSize StagingRing::reserve(VkCommandBuffer cb, VkBuffer dst, VkDeviceSize dstOffset,
                                  VkDeviceSize bytes) {
    const VkDeviceSize offset = space(bytes);
    VkBufferCopy copy{offset, dstOffset, bytes};
    vkCmdCopyBuffer(cb, buffer_.handle(), dst, 1, &copy);
    uploadedThisFrame_ += bytes;
    ++copiesThisFrame_;
    return offset;
}

void StagingRing::upload(VkCommandBuffer cb, VkBuffer dst, VkDeviceSize dstOffset, const void* data,
                         VkDeviceSize bytes) {
    if (bytes == 0) return;
    buffer_.write(reserve(cb, dst, dstOffset, bytes), data, bytes);
}

void StagingRing::uploadAll(VkCommandBuffer cb, VkBuffer dst, std::span<const StagedPiece> pieces) {
    VkDeviceSize total = 0;
    for (const StagedPiece& p : pieces) total += p.bytes;
    if (total == 0) return;
    VkDeviceSize at = space(total);
    regionsOfAll_.clear();
    for (const StagedPiece& p : pieces) {
        if (p.bytes == 0) continue;
        buffer_.write(at, p.data, p.bytes);
        regionsOfAll_.push_back({at, p.dstOffset, p.bytes});
        at += p.bytes;
    }
    vkCmdCopyBuffer(cb, buffer_.handle(), dst, std::uint32_t(regionsOfAll_.size()),
                    regionsOfAll_.data());
    uploadedThisFrame_ += total;
    ++copiesThisFrame_;
}

void* StagingRing::uploadInPlace(VkCommandBuffer cb, VkBuffer dst, VkDeviceSize dstOffset,
                                 VkDeviceSize bytes) {
    if (bytes == 0) return nullptr;
    const VkDeviceSize offset = reserve(cb, dst, dstOffset, bytes);
    if (buffer_.placement().flushAfterWrite) pendingFlushes_.push_back({&buffer_, offset, bytes});
    return static_cast<std::uint8_t*>(buffer_.mapped()) + offset;
}

void StagingRing::flushPending() {
    for (const PendingFlush& p : pendingFlushes_) p.buffer->flush(p.offset, p.bytes);
    pendingFlushes_.clear();
}

void StagingRing::recordBarrier(VkCommandBuffer cb, VkPipelineStageFlags dstStage,
                                VkAccessFlags dstAccess) {
    if (copiesThisFrame_ == 0) return;
    VkMemoryBarrier b{VK_STRUCTURE_TYPE_MEMORY_BARRIER};
    b.srcAccessMask = VK_ACCESS_TRANSFER_WRITE_BIT;
    b.dstAccessMask = dstAccess;
    vkCmdPipelineBarrier(cb, VK_PIPELINE_STAGE_TRANSFER_BIT, dstStage, 0, 1, &b, 0, nullptr, 0,
                         nullptr);
}

void StagingRing::retire(std::uint64_t frame) {
    while (!regions_.empty() && regions_.front().frame <= frame) {
        used_ -= regions_.front().bytes;
        regions_.pop_front();
    }
    if (regions_.empty()) frameOpen_ = false;
    outgrown_.remove_if([&](const Outgrown& o) { return o.lastFrame <= frame; });
}

HostWrite uploadToBuffer(StagingRing& ring, VkCommandBuffer cb, VulkanBuffer& dst,
                         VkDeviceSize dstOffset, const void* data, VkDeviceSize bytes) {
    switch (dst.placement().hostWrite) {
    case HostWrite::Direct:
        dst.write(dstOffset, data, bytes);
        return HostWrite::Direct;
    case HostWrite::Staged:
        if (dstOffset > dst.size() || bytes > dst.size() - dstOffset)
            throw VulkanError("uploadToBuffer: " + std::to_string(bytes) + " bytes at " +
                              std::to_string(dstOffset) + " past the end of a " +
                              std::to_string(dst.size()) + "-byte buffer");
        ring.upload(cb, dst.handle(), dstOffset, data, bytes);
        return HostWrite::Staged;
    case HostWrite::None:
        break;
    }
    throw VulkanError("uploadToBuffer: the host does not write this buffer (its class has no "
                      "host writes)");
}

} // namespace voxtier
