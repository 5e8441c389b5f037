#include "impostor_cache/far_residency.hpp"

#include "device/vulkan_check.hpp"

#include <algorithm>
#include <cstring>
#include <iterator>
#include <string>
#include <utility>
#include <vector>

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
    // Past the device's range a buffer below it grows to the range (its new free tail may still
    // hold what is asked; the caller's allocation says); only a buffer at the range cannot grow.
    if (words * 4 > limit && capacityWords_ * 4 < limit) words = limit / 4;
    if (words * 4 > limit)
        throw VulkanError("far pass: the resident snapshots need " + std::to_string(words * 4) +
                          " bytes, past the device's storage buffer range of " +
                          std::to_string(limit));
    VulkanBuffer bigger(device_, words * 4, kUsage, BufferClass::DeviceOnly);
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

template <class Keep> void FarResidency::freeUnless(Keep&& keep, FarResidencyStats& st) {
    for (auto it = entries_.begin(); it != entries_.end();) {
        if (keep(*it)) {
            ++it;
            continue;
        }
        release(it->second.offset, it->second.words);
        usedWords_ -= it->second.words;
        ++st.snapshotsFreed;
        if (const auto l = byLineage_.find(it->second.cells.lineage);
            l != byLineage_.end() && l->second == it->first)
            byLineage_.erase(l);
        it = entries_.erase(it);
    }
}

void FarResidency::sweep(const std::unordered_set<const void*>& keep, FarResidencyStats& st) {
    freeUnless(
        [&](const auto& e) {
            return e.second.cells.owner.use_count() > 1 || keep.count(e.first) > 0;
        },
        st);
}

void FarResidency::evictUnneeded(const std::unordered_set<const void*>& needed,
                                 FarResidencyStats& st) {
    freeUnless([&](const auto& e) { return needed.count(e.first) > 0; }, st);
}

void FarResidency::stage(const std::uint8_t* from, std::size_t bytes, VkDeviceSize deviceByte) {
    // The cells stay alive until recordUploads: the entry (or the batch) holds their owner.
    copies_.push_back({from, VkDeviceSize(bytes), deviceByte});
}

std::vector<std::uint32_t> FarResidency::update(const FarBatch& batch, FarResidencyStats* stats) {
    FarResidencyStats st;
    copies_.clear();
    // A snapshot new to the device whose predecessor (same lineage) nobody else holds any more
    // may take over its range: the predecessor is kept through the sweep for that.
    std::unordered_set<const void*> predecessors;
    for (const FarSnapshotCells& s : batch.snapshots) {
        if (!s.lineage || entries_.count(s.owner.get())) continue;
        if (const auto l = byLineage_.find(s.lineage); l != byLineage_.end())
            predecessors.insert(l->second);
    }
    sweep(predecessors, st);

    std::vector<std::uint32_t> offsets(batch.snapshots.size());
    for (std::size_t k = 0; k < batch.snapshots.size(); ++k) {
        const FarSnapshotCells& s = batch.snapshots[k];
        const void* key = s.owner.get();
        if (auto it = entries_.find(key); it != entries_.end()) {
            offsets[k] = it->second.offset;
            continue;
        }
        const std::size_t rowBytes = std::size_t(s.width()) * 2, rows = std::size_t(s.height());
        // A refresh: the rows that differ from what the device holds, into the same range.
        if (const auto l = s.lineage ? byLineage_.find(s.lineage) : byLineage_.end();
            l != byLineage_.end()) {
            const auto old = entries_.find(l->second);
            if (old != entries_.end() && old->second.cells.owner.use_count() == 1 &&
                old->second.cells.cellRange == s.cellRange) {
                Entry e = std::move(old->second);
                entries_.erase(old);
                const VkDeviceSize base = VkDeviceSize(e.offset) * 4;
                for (std::size_t r = 0; r < rows;) {
                    const auto differs = [&](std::size_t row) {
                        return std::memcmp(s.cells + row * rowBytes, e.cells.cells + row * rowBytes,
                                           rowBytes) != 0;
                    };
                    if (!differs(r)) {
                        ++r;
                        continue;
                    }
                    std::size_t end = r + 1;
                    while (end < rows && differs(end)) ++end;
                    stage(s.cells + r * rowBytes, (end - r) * rowBytes, base + r * rowBytes);
                    st.bytesUploaded += (end - r) * rowBytes;
                    r = end;
                }
                e.cells = s;
                offsets[k] = e.offset;
                entries_.emplace(key, std::move(e));
                byLineage_[s.lineage] = key;
                ++st.snapshotsUploaded;
                ++st.refreshesInPlace;
                continue;
            }
        }
        const std::uint32_t words = std::max<std::uint32_t>(wordsOf(s), 1);
        std::uint32_t offset = 0;
        if (!allocate(words, offset)) {
            // Snapshots the cache still holds but this frame does not draw leave the device first
            // (a later frame uploads them again); the buffer grows only for what a frame needs,
            // up to the device's storage buffer range (finer snapshots, issue 29, reach it on
            // lavapipe's 128 MiB).
            std::unordered_set<const void*> needed;
            for (const FarSnapshotCells& n : batch.snapshots) needed.insert(n.owner.get());
            evictUnneeded(needed, st);
            if (!allocate(words, offset)) {
                grow(capacityWords_ + words);
                if (!allocate(words, offset))
                    throw VulkanError(
                        "far pass: the frame's snapshots do not fit the device's storage buffer "
                        "range of " +
                        std::to_string(device_.properties().limits.maxStorageBufferRange) +
                        " bytes");
            }
        }
        entries_.emplace(key, Entry{s, offset, words});
        if (s.lineage) byLineage_[s.lineage] = key;
        offsets[k] = offset;
        stage(s.cells, rowBytes * rows, VkDeviceSize(offset) * 4);
        st.bytesUploaded += rowBytes * rows;
        ++st.snapshotsUploaded;
    }
    // Predecessors no refresh took over (another cell range) go now.
    sweep({}, st);
    totals_.snapshotsUploaded += st.snapshotsUploaded;
    totals_.bytesUploaded += st.bytesUploaded;
    totals_.refreshesInPlace += st.refreshesInPlace;
    totals_.snapshotsFreed += st.snapshotsFreed;
    if (stats) {
        stats->snapshotsUploaded += st.snapshotsUploaded;
        stats->bytesUploaded += st.bytesUploaded;
        stats->refreshesInPlace += st.refreshesInPlace;
        stats->snapshotsFreed += st.snapshotsFreed;
    }
    return offsets;
}

void FarResidency::recordUploads(GpuFrame& frame) {
    if (!retiredWords_ && copies_.empty()) return;
    VkCommandBuffer cb = frame.commandBuffer();
    if (retiredWords_) {
        const VkBufferCopy all{0, 0, retiredWords_ * 4};
        vkCmdCopyBuffer(cb, retired_.handle(), buffer_.handle(), 1, &all);
        if (!copies_.empty())
            bufferBarrier(cb, buffer_.handle(), VK_PIPELINE_STAGE_TRANSFER_BIT,
                          VK_ACCESS_TRANSFER_WRITE_BIT, VK_PIPELINE_STAGE_TRANSFER_BIT,
                          VK_ACCESS_TRANSFER_WRITE_BIT);
        // The old buffer lives until this frame has copied out of it.
        frame.keepUntilDone(std::move(retired_));
        retiredWords_ = 0;
    }
    for (const Copy& c : copies_)
        frame.ring().upload(cb, buffer_.handle(), c.deviceByte, c.from, c.bytes);
    copies_.clear();
    bufferBarrier(cb, buffer_.handle(), VK_PIPELINE_STAGE_TRANSFER_BIT,
                  VK_ACCESS_TRANSFER_WRITE_BIT, VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT,
                  VK_ACCESS_SHADER_READ_BIT);
}

} // namespace voxtier
