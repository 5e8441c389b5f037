#pragma once
// Device residency of the far tier's snapshots (CONTRACT.md §6, the far pass on Vulkan): each
// snapshot a GPU far pass draws is uploaded once, when first drawn, into one device storage
// buffer (two bytes a cell, two cells a word), at a word offset found first-fit among the free
// ranges; the buffer doubles when nothing fits, up to the device's storage buffer range, where
// the snapshots the frame does not draw leave first. A resident snapshot is held by its owner
// (FarSnapshotCells::owner), and freed at the next update once nobody else holds it (the
// snapshot cache evicted it under its byte budget, or an edit's refresh replaced it): the device
// holds what the cache holds, plus what frames still hold. A refreshed snapshot (the same
// lineage, the same cell range) takes over its predecessor's range and uploads only the rows of
// cells that differ from it.
#include "device/gpu_frame.hpp"
#include "device/vulkan_device.hpp"
#include "impostor_cache/far_batch.hpp"

#include <cstdint>
#include <map>
#include <memory>
#include <unordered_map>
#include <unordered_set>
#include <vector>

namespace voxtier {

struct FarResidencyStats {
    /// Snapshots uploaded (whole, or a refresh's changed rows) and the bytes copied.
    std::uint64_t snapshotsUploaded = 0, bytesUploaded = 0;
    std::uint64_t refreshesInPlace = 0; ///< of those, refreshes that took over their predecessor
    std::uint64_t snapshotsFreed = 0;   ///< nobody else held them any more
    std::uint64_t growths = 0;          ///< the buffer was re-created larger
};

class FarResidency {
  public:
    explicit FarResidency(VulkanDevice& device);
    FarResidency(const FarResidency&) = delete;
    FarResidency& operator=(const FarResidency&) = delete;

    /// Frees the ranges of snapshots nobody else holds, makes every snapshot of `batch` resident
    /// and returns each one's word offset, in batch order. The copies are recorded by
    /// recordUploads, into the same frame; until then buffer() may be a new, larger buffer.
    std::vector<std::uint32_t> update(const FarBatch& batch, FarResidencyStats* stats = nullptr);
    /// Records this update's copies into `frame` (the growth copy, then the cells through the
    /// frame's staging ring) and the barrier that makes them visible to compute shaders.
    void recordUploads(GpuFrame& frame);

    VkBuffer buffer() const { return buffer_.handle(); }
    std::uint64_t residentBytes() const { return usedWords_ * 4; }
    std::size_t residentSnapshots() const { return entries_.size(); }
    const FarResidencyStats& totals() const { return totals_; }

  private:
    struct Entry {
        FarSnapshotCells cells; ///< holds the owner: its cells are what the device range holds
        std::uint32_t offset = 0, words = 0;
    };
    bool allocate(std::uint32_t words, std::uint32_t& offset);
    void release(std::uint32_t offset, std::uint32_t words);
    void grow(std::uint64_t minWords);
    /// Frees every entry only this object holds, except those in `keep`.
    void sweep(const std::unordered_set<const void*>& keep, FarResidencyStats& stats);
    /// Frees every resident snapshot not in `needed`, held elsewhere or not.
    void evictUnneeded(const std::unordered_set<const void*>& needed, FarResidencyStats& stats);
    /// Frees every resident snapshot (an entries_ element) for which keep(element) is false;
    /// `keep` is asked from every core at once.
    template <class Keep> void freeUnless(Keep&& keep, FarResidencyStats& stats);
    /// Frees the entry of `key`, if resident.
    void freeEntry(const void* key, FarResidencyStats& stats);
    /// Notes `bytes` bytes of `from` for a copy to byte `deviceByte` of the buffer.
    void stage(const std::uint8_t* from, std::size_t bytes, VkDeviceSize deviceByte);

    VulkanDevice& device_;
    VulkanBuffer buffer_, retired_;
    std::uint64_t capacityWords_ = 0, usedWords_ = 0;
    std::map<std::uint32_t, std::uint32_t> free_; ///< offset -> words, coalesced
    std::unordered_map<const void*, Entry> entries_;
    std::unordered_map<std::uint64_t, const void*> byLineage_; ///< the lineage's latest entry
    struct Copy {
        const std::uint8_t* from; ///< held by the entry's owner until recordUploads
        VkDeviceSize bytes, deviceByte;
    };
    std::vector<StagedPiece> pieces_;              ///< recordUploads', kept between frames
    std::vector<Copy> copies_;                     ///< this update's, recorded by recordUploads
    std::vector<std::vector<const void*>> doomed_; ///< freeUnless's, per range of buckets
    std::uint64_t retiredWords_ = 0;               ///< words of retired_ to copy into buffer_ first
    /// The cache and drop count of the last update's batch (FarBatch::cacheUid, cacheDrops), and
    /// the updates still to sweep since they last changed: enough for the frames in flight
    /// (GpuFrames' slots) that held a dropped snapshot to let it go.
    std::uint64_t sweptCache_ = 0, sweptDrops_ = 0;
    int sweepsOwed_ = 0;
    static constexpr int kSweepsAfterADrop = 4;
    FarResidencyStats totals_;
};

} // namespace voxtier
