#include "impostor_cache/far_residency.hpp"

#include "device/vulkan_check.hpp"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

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

void FarResidency::freeEntry(const void* key, FarResidencyStats& st) {
    const auto it = entries_.find(key);
    if (it == entries_.end()) return;
    release(it->second.offset, it->second.words);
    usedWords_ -= it->second.words;
    ++st.snapshotsFreed;
    if (const auto l = byLineage_.find(it->second.cells.lineage);
        l != byLineage_.end() && l->second == it->first)
        byLineage_.erase(l);
    entries_.erase(it);
}

template <class Keep> void FarResidency::freeUnless(Keep&& keep, FarResidencyStats& st) {
    // Which entries go, found on every core over ranges of the map's buckets (each entry's owner
    // count is a cache miss apiece, and a moving camera under the error budget keeps ~10,000
    // snapshots resident), then freed here. The free ranges coalesce, so the buffer's layout is
    // the same whatever order they are freed in.
    constexpr std::size_t kBucketsPerTask = 1024;
    const std::size_t buckets = entries_.bucket_count();
    const std::size_t tasks = (buckets + kBucketsPerTask - 1) / kBucketsPerTask;
    doomed_.resize(std::max(doomed_.size(), tasks));
    tbb::parallel_for(std::size_t(0), tasks, [&](std::size_t t) {
        std::vector<const void*>& mine = doomed_[t];
        mine.clear();
        for (std::size_t b = t * kBucketsPerTask; b < std::min(buckets, (t + 1) * kBucketsPerTask);
             ++b)
            for (auto it = entries_.cbegin(b); it != entries_.cend(b); ++it)
                if (!keep(*it)) mine.push_back(it->first);
    });
    for (std::size_t t = 0; t < tasks; ++t)
        for (const void* key : doomed_[t]) freeEntry(key, st);
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
    // Where each snapshot already resident lies, looked up on every core (most of a frame's
    // snapshots: a still camera's all). The sweeps below never free one of them: the batch holds
    // it, and a freed range is the only thing that moves (a grown buffer keeps every offset).
    constexpr std::uint32_t kNew = ~0u;
    const std::size_t count = batch.snapshots.size();
    std::vector<std::uint32_t> offsets(count);
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, count, 256), [&](const auto& range) {
        for (std::size_t k = range.begin(); k != range.end(); ++k) {
            const auto it = entries_.find(batch.snapshots[k].owner.get());
            offsets[k] = it != entries_.end() ? it->second.offset : kNew;
        }
    });
    // A snapshot new to the device whose predecessor (same lineage) nobody else holds any more
    // may take over its range: the predecessor is kept through the sweep for that.
    std::unordered_set<const void*> predecessors;
    for (std::size_t k = 0; k < count; ++k) {
        const FarSnapshotCells& s = batch.snapshots[k];
        if (offsets[k] != kNew || !s.lineage) continue;
        if (const auto l = byLineage_.find(s.lineage); l != byLineage_.end())
            predecessors.insert(l->second);
    }
    // The sweep reads every resident snapshot's owner count, a miss apiece over all the cache
    // holds: half of the far pass's host recording on the 2,000-tank army under the budget
    // (lavapipe, 2 cores). A snapshot only this residency holds appears only once the cache has
    // dropped it, and once the frames that held it then have let go: so the updates sweep from a
    // change of the batch's cache or of its drops until kSweepsAfterADrop updates later, and when
    // a snapshot does not fit (below), as before every update. (Whoever holds a dropped snapshot
    // longer, not a renderer, leaves its device copy until the next drop or until space runs
    // short.)
    if (batch.cacheUid == 0 || batch.cacheUid != sweptCache_ || batch.cacheDrops != sweptDrops_)
        sweepsOwed_ = kSweepsAfterADrop;
    sweptCache_ = batch.cacheUid;
    sweptDrops_ = batch.cacheDrops;
    bool swept = false;
    const auto sweepOnce = [&] {
        if (!swept) sweep(predecessors, st);
        swept = true;
    };
    if (sweepsOwed_ > 0) {
        --sweepsOwed_;
        sweepOnce();
    }

    for (std::size_t k = 0; k < count; ++k) {
        if (offsets[k] != kNew) continue;
        const FarSnapshotCells& s = batch.snapshots[k];
        const void* key = s.owner.get();
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
        const VkDeviceSize range = device_.properties().limits.maxStorageBufferRange;
        // Below the device's storage buffer range the buffer grows when nothing fits: the device
        // then holds what the cache holds (its byte budget bounds both), and a snapshot drawn
        // again later is not uploaded again. An animated crowd shows each animation frame's
        // snapshots in turn: evicting what a frame does not draw first uploaded ~1,000 snapshots,
        // ~2 MB in as many copies, at every animation step of the 2,000-tank army under the error
        // budget, and again each cycle. At the range (finer snapshots, issue 29, reach
        // lavapipe's 128 MiB) what this frame does not draw leaves the device first, and a later
        // frame uploads it again.
        bool placed = allocate(words, offset);
        if (!placed) {
            sweepOnce(); // what the cache dropped first
            placed = allocate(words, offset);
        }
        if (!placed && capacityWords_ * 4 < range) {
            grow(capacityWords_ + words);
            placed = allocate(words, offset);
        }
        if (!placed) {
            std::unordered_set<const void*> needed;
            for (const FarSnapshotCells& n : batch.snapshots) needed.insert(n.owner.get());
            evictUnneeded(needed, st);
            if (!allocate(words, offset))
                throw VulkanError(
                    "far pass: the frame's snapshots do not fit the device's storage buffer "
                    "range of " +
                    std::to_string(range) + " bytes");
        }
        entries_.emplace(key, Entry{s, offset, words});
        if (s.lineage) byLineage_[s.lineage] = key;
        offsets[k] = offset;
        stage(s.cells, rowBytes * rows, VkDeviceSize(offset) * 4);
        st.bytesUploaded += rowBytes * rows;
        ++st.snapshotsUploaded;
    }
    // Predecessors no refresh took over (another cell range) go now. Nothing else can: every
    // other entry only this object held went in a sweep above or waits for the next one, and
    // every one added since holds a snapshot of the batch.
    for (const void* key : predecessors)
        if (const auto it = entries_.find(key);
            it != entries_.end() && it->second.cells.owner.use_count() <= 1)
            freeEntry(key, st);
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
    // One copy command of as many regions, not a command per snapshot (StagingRing::uploadAll).
    pieces_.clear();
    for (const Copy& c : copies_) pieces_.push_back({c.from, c.bytes, c.deviceByte});
    frame.ring().uploadAll(cb, buffer_.handle(), pieces_);
    copies_.clear();
    bufferBarrier(cb, buffer_.handle(), VK_PIPELINE_STAGE_TRANSFER_BIT,
                  VK_ACCESS_TRANSFER_WRITE_BIT, VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT,
                  VK_ACCESS_SHADER_READ_BIT);
}

} // namespace voxtier
