#pragma once
// GPU residency of voxel data for the near tier: one R8_UINT 3D atlas holding every (model,
// frame) that a sprite has needed so far, once, shared by all entities (lavapipe has no
// descriptor indexing, and one atlas keeps the whole near tier a single instanced draw,
// CONTRACT.md §6), plus one storage buffer with 256 packed colours per resident model.
// Edits re-upload only the dirty box of a frame (VoxelModel::dirtySince).
#include "core/sprite.hpp"
#include "core/voxel_model.hpp"
#include "device/vulkan_device.hpp"
#include "volumetric/atlas_packer.hpp"

#include <cstdint>
#include <functional>
#include <memory>
#include <span>
#include <unordered_map>
#include <vector>

namespace voxtier {

struct ResidencyStats {
    std::uint64_t bytesUploaded = 0; ///< voxel bytes copied to the atlas
    std::uint64_t regions = 0;       ///< buffer -> image copy regions
    std::uint64_t fullFrames = 0;    ///< of those, whole frames (new, or the edit log ran out)
    std::uint64_t atlasGrowths = 0;  ///< times the atlas image was re-created larger
    double milliseconds = 0.0;       ///< host packing + submit + wait
    ResidencyStats& operator+=(const ResidencyStats& o);
};

class VoxelResidency {
  public:
    /// `waitForReaders` waits until no frame in flight reads the atlas or the palettes: called
    /// before either is replaced by a larger one (rare: both grow by doubling), since frames
    /// recorded earlier still read the old ones.
    explicit VoxelResidency(VulkanDevice& device, std::function<void()> waitForReaders = {});
    ~VoxelResidency();
    VoxelResidency(const VoxelResidency&) = delete;
    VoxelResidency& operator=(const VoxelResidency&) = delete;

    /// Makes the (model, frame) of every visible sprite resident and current: new frames are
    /// uploaded whole, edited frames only in their dirty box. Blocks until the copies are done.
    ResidencyStats update(const std::vector<std::shared_ptr<VoxelModel>>& models,
                          std::span<const SpriteSetup* const> sprites);
    /// SpriteGpu::atlas for a resident frame: xyz = atlas origin, w = palette base index.
    glm::uvec4 entry(const VoxelModel& model, int frame) const;

    VkImageView atlasView() const { return atlas_.view(); }
    VkBuffer paletteBuffer() const { return palettes_.handle(); }
    VkDeviceSize paletteBytes() const { return palettes_.size(); }
    VkExtent3D atlasExtent() const { return atlas_.extent(); }
    /// Changes whenever the atlas image or the palette buffer is re-created (descriptors go stale).
    std::uint64_t generation() const { return generation_; }
    const AtlasPacker& packer() const { return packer_; }
    /// Totals since construction.
    const ResidencyStats& totals() const { return totals_; }

  private:
    struct Resident {
        std::uint64_t version = 0; ///< model version the atlas holds
        std::uint32_t paletteBase = 0;
        std::vector<glm::ivec3> origin; ///< per frame
        std::vector<bool> present;      ///< per frame
    };
    struct Upload {
        const VoxelGrid* grid;
        Box3i box;         ///< in the frame's voxel coordinates
        glm::ivec3 origin; ///< of the frame in the atlas
    };

    void createAtlas(std::uint32_t depth, VkCommandBuffer cb, bool copyOld);
    void ensurePaletteCapacity(std::size_t entries);
    /// Palette entries [first, first + count) of the mirror onto the device: written directly,
    /// or marked for the next update's staged copy (then the whole mirror goes).
    void writePalettes(std::size_t first, std::size_t count);

    VulkanDevice& device_;
    std::function<void()> waitForReaders_;
    AtlasPacker packer_;
    VulkanImage atlas_;
    VulkanImage retired_; ///< the previous atlas while a growth copy is in flight
    VulkanBuffer palettes_;
    VulkanBuffer staging_;
    std::vector<std::uint32_t> paletteMirror_;
    bool paletteStaged_ = false; ///< the device's palettes wait for a staged copy of the mirror
    std::unordered_map<std::uint64_t, Resident> residents_; ///< by VoxelModel::uid()
    std::uint32_t nextPaletteSlot_ = 0;
    std::uint64_t generation_ = 0;
    ResidencyStats totals_;
    VkCommandBuffer cb_ = VK_NULL_HANDLE;
};

} // namespace voxtier
