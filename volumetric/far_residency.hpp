#pragma once
// Device residency of the far tier's snapshots (DESIGN.md §6, the far pass on Vulkan): each
// snapshot a GPU far pass draws is uploaded once, when first drawn, into one device storage
// buffer (two bytes a cell, two cells a word), at a word offset found first-fit among the free
// ranges; the buffer doubles when nothing fits. A resident snapshot is keyed by its owner
// (FarSnapshotCells::owner) and watched through a weak pointer: once nobody holds the snapshot
// any more (the snapshot cache evicted it under its byte budget, or an edit's refresh replaced
// it), its range is freed at the next update. So the device holds at most what the cache holds,
// plus what frames still hold.
#include "core/far_batch.hpp"
#include "volumetric/vulkan_device.hpp"

#include <cstdint>
#include <map>
#include <memory>
#include <unordered_map>
#include <vector>

namespace voxtier {

struct FarResidencyStats {
    std::uint64_t snapshotsUploaded = 0, bytesUploaded = 0;
    std::uint64_t snapshotsFreed = 0; ///< their owners dropped them
    std::uint64_t growths = 0;        ///< the buffer was re-created larger
};

class FarResidency {
  public:
    explicit FarResidency(VulkanDevice& device);
    FarResidency(const FarResidency&) = delete;
    FarResidency& operator=(const FarResidency&) = delete;

    /// Frees the ranges of snapshots nobody holds, makes every snapshot of `batch` resident
    /// (staging the new ones) and returns each one's word offset, in batch order. The copies
    /// are recorded by recordUploads; until then buffer() may be a new, larger buffer.
    std::vector<std::uint32_t> update(const FarBatch& batch, FarResidencyStats* stats = nullptr);
    /// Records this update's copies (growth copy, then staged snapshots) and the barrier that
    /// makes them visible to compute shaders.
    void recordUploads(VkCommandBuffer cb);
    /// To be called once the command buffer of recordUploads has completed.
    void uploadsDone();

    VkBuffer buffer() const { return buffer_.handle(); }
    std::uint64_t residentBytes() const { return usedWords_ * 4; }
    std::size_t residentSnapshots() const { return entries_.size(); }
    const FarResidencyStats& totals() const { return totals_; }

  private:
    struct Entry {
        std::weak_ptr<const void> owner;
        std::uint32_t offset = 0, words = 0;
    };
    bool allocate(std::uint32_t words, std::uint32_t& offset);
    void release(std::uint32_t offset, std::uint32_t words);
    void grow(std::uint64_t minWords);

    VulkanDevice& device_;
    VulkanBuffer buffer_, retired_, staging_;
    std::uint64_t capacityWords_ = 0, usedWords_ = 0;
    std::map<std::uint32_t, std::uint32_t> free_; ///< offset -> words, coalesced
    std::unordered_map<const void*, Entry> entries_;
    std::vector<VkBufferCopy> copies_; ///< staging -> buffer, this update
    std::uint64_t retiredWords_ = 0;   ///< words of retired_ to copy into buffer_ first
    FarResidencyStats totals_;
};

} // namespace voxtier
