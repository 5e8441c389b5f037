#include "volumetric/far_residency.hpp"

#include "volumetric/vulkan_check.hpp"

#include <algorithm>
#include <cstring>
#include <iterator>
#include <string>
#include <utility>

namespace voxtier {

namespace {

constexpr VkBufferUsageFlags kUsage = VK_BUFFER_USAGE_STORAGE_BUFFER_BIT |
                                      VK_BUFFER_USAGE_TRANSFER_DST_BIT |
                                      VK_BUFFER_USAGE_TRANSFER_SRC_BIT;

std::uint32_t wordsOf(const FarSnapshotCells& s) {
    const std::uint64_t cells = std::uint64_t(s.width()) * std::uint64_t(s.height());
    return std::uint32_t((cells + 1) / 2);
}

} // namespace

FarResidency::FarResidency(VulkanDevice& device) : device_(device) {
    grow(1u << 16); // 256 KiB to start
}

void FarResidency::grow(std::uint64_t minWords) {
    std::uint64_t words = std::max<std::uint64_t>(capacityWords_, 1u << 16);
    while (words < minWords) words *= 2;
    if (capacityWords_) words = std::max(words, 2 * capacityWords_);
    const VkDeviceSize limit = device_.properties().limits.maxStorageBufferRange;
    if (words * 4 > limit)
        throw VulkanError("far pass: the resident snapshots need " + std::to_string(words * 4) +
                          " bytes, past the device's storage buffer range of " +
                          std::to_string(limit));
    VulkanBuffer bigger(device_, words * 4, kUsage, false);
    if (capacityWords_) {
        // The old contents move over in the next recorded upload, before anything new.
        if (!retired_) { // a second growth before the copy keeps the first buffer's contents
            retired_ = std::move(buffer_);
            retiredWords_ = capacityWords_;
        }
        ++totals_.growths;
    }
    // The new tail is free (merged with a free range ending at the old end).
    release(std::uint32_t(capacityWords_), std::uint32_t(words - capacityWords_));
    buffer_ = std::move(bigger);
    capacityWords_ = words;
}

bool FarResidency::allocate(std::uint32_t words, std::uint32_t& offset) {
    for (auto it = free_.begin(); it != free_.end(); ++it) {
        if (it->second < words) continue;
        offset = it->first;
        const std::uint32_t left = it->second - words;
        free_.erase(it);
        if (left) free_.emplace(offset + words, left);
        usedWords_ += words;
        return true;
    }
    return false;
}

void FarResidency::release(std::uint32_t offset, std::uint32_t words) {
    if (!words) return;
    auto next = free_.lower_bound(offset);
    if (next != free_.begin()) {
        auto prev = std::prev(next);
        if (prev->first + prev->second == offset) {
            offset = prev->first;
            words += prev->second;
            free_.erase(prev);
        }
    }
    if (next != free_.end() && offset + words == next->first) {
        words += next->second;
        free_.erase(next);
    }
    free_.emplace(offset, words);
}

std::vector<std::uint32_t> FarResidency::update(const FarBatch& batch, FarResidencyStats* stats) {
    FarResidencyStats st;
    // Snapshots nobody holds any more (evicted or replaced): their ranges are free again.
    for (auto it = entries_.begin(); it != entries_.end();) {
        if (it->second.owner.expired()) {
            release(it->second.offset, it->second.words);
            usedWords_ -= it->second.words;
            ++st.snapshotsFreed;
            it = entries_.erase(it);
        } else {
            ++it;
        }
    }
    std::vector<std::uint32_t> offsets(batch.snapshots.size());
    struct Pending {
        std::size_t snapshot;
        std::uint32_t offset, words;
    };
    std::vector<Pending> pending;
    std::uint64_t stagedWords = 0;
    for (std::size_t k = 0; k < batch.snapshots.size(); ++k) {
        const FarSnapshotCells& s = batch.snapshots[k];
        const void* key = s.owner.get();
        if (auto it = entries_.find(key); it != entries_.end()) {
            offsets[k] = it->second.offset;
            continue;
        }
        const std::uint32_t words = std::max<std::uint32_t>(wordsOf(s), 1);
        std::uint32_t offset = 0;
        if (!allocate(words, offset)) {
            grow(capacityWords_ + words);
            if (!allocate(words, offset))
                throw VulkanError("far pass: no room for a snapshot after growing");
        }
        entries_.emplace(key, Entry{s.owner, offset, words});
        offsets[k] = offset;
        pending.push_back({k, offset, words});
        stagedWords += words;
    }
    copies_.clear();
    if (stagedWords) {
        if (!staging_ || staging_.size() < stagedWords * 4) {
            VkDeviceSize size = staging_ ? staging_.size() : 1u << 16;
            while (size < stagedWords * 4) size *= 2;
            staging_ = VulkanBuffer(device_, size, VK_BUFFER_USAGE_TRANSFER_SRC_BIT, true);
        }
        auto* dst = static_cast<std::uint8_t*>(staging_.mapped());
        VkDeviceSize at = 0;
        for (const Pending& p : pending) {
            const FarSnapshotCells& s = batch.snapshots[p.snapshot];
            const std::size_t bytes =
                std::size_t(s.width()) * std::size_t(s.height()) * 2; // two bytes a cell
            if (bytes) std::memcpy(dst + at, s.cells, bytes);
            if (bytes < std::size_t(p.words) * 4)
                std::memset(dst + at + bytes, 0, p.words * 4 - bytes);
            copies_.push_back({at, VkDeviceSize(p.offset) * 4, VkDeviceSize(p.words) * 4});
            at += VkDeviceSize(p.words) * 4;
            st.bytesUploaded += bytes;
        }
        st.snapshotsUploaded = pending.size();
    }
    totals_.snapshotsUploaded += st.snapshotsUploaded;
    totals_.bytesUploaded += st.bytesUploaded;
    totals_.snapshotsFreed += st.snapshotsFreed;
    if (stats) {
        stats->snapshotsUploaded += st.snapshotsUploaded;
        stats->bytesUploaded += st.bytesUploaded;
        stats->snapshotsFreed += st.snapshotsFreed;
    }
    return offsets;
}

void FarResidency::recordUploads(VkCommandBuffer cb) {
    if (!retiredWords_ && copies_.empty()) return;
    if (retiredWords_) {
        const VkBufferCopy all{0, 0, retiredWords_ * 4};
        vkCmdCopyBuffer(cb, retired_.handle(), buffer_.handle(), 1, &all);
        if (!copies_.empty())
            bufferBarrier(cb, buffer_.handle(), VK_PIPELINE_STAGE_TRANSFER_BIT,
                          VK_ACCESS_TRANSFER_WRITE_BIT, VK_PIPELINE_STAGE_TRANSFER_BIT,
                          VK_ACCESS_TRANSFER_WRITE_BIT);
    }
    if (!copies_.empty())
        vkCmdCopyBuffer(cb, staging_.handle(), buffer_.handle(), std::uint32_t(copies_.size()),
                        copies_.data());
    bufferBarrier(cb, buffer_.handle(), VK_PIPELINE_STAGE_TRANSFER_BIT,
                  VK_ACCESS_TRANSFER_WRITE_BIT, VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT,
                  VK_ACCESS_SHADER_READ_BIT);
}

void FarResidency::uploadsDone() {
    retired_.reset();
    retiredWords_ = 0;
    copies_.clear();
}

} // namespace voxtier
