#pragma once
// GPU residency of voxel data for the near tier: one R8_UINT 3D atlas holding every (model,
// frame) that a sprite has needed so far, once, shared by all entities (lavapipe has no
// descriptor indexing, and one atlas keeps the whole near tier a single instanced draw,
// CONTRACT.md §6), plus one storage buffer with 256 packed colours per resident model and one
// with every resident frame's brick occupancy words (VoxelModel::bricks, the kernel's empty-space
// skipping). Edits re-upload only the dirty box of a frame (VoxelModel::dirtySince) and the
// frame's occupancy words.
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

    /// The sprites that show each model and each model frame first, in the order given: what
    /// update() walks every visible sprite to find (each a cache miss at 100,000 sprites). A
    /// caller that knows its sprites show the same (model, frame)s in the same order as at the
    /// update that filled it keeps `valid`, and that update's answer is used again.
    struct FirstShowings {
        bool valid = false;
        std::vector<std::uint32_t> firsts;
    };
    static constexpr std::uint32_t kNotShown = 0xFFFFFFFFu;
    /// FirstShowings::firsts of a drawn order, found from sprites in another order (a store's,
    /// read in sequence) and each one's place in the drawn order (kNotShown: not drawn): what
    /// update() finds by walking the drawn order, without its cache miss a sprite.
    static std::vector<std::uint32_t>
    firstShowingsAt(const std::vector<std::shared_ptr<VoxelModel>>& models,
                    std::span<const SpriteSetup* const> sprites,
                    std::span<const std::uint32_t> places);
    /// Makes the (model, frame) of every visible sprite resident and current: new frames are
    /// uploaded whole, edited frames only in their dirty box. Blocks until the copies are done.
    /// `firsts` (optional): used where valid, else found and kept there.
    ResidencyStats update(const std::vector<std::shared_ptr<VoxelModel>>& models,
                          std::span<const SpriteSetup* const> sprites,
                          FirstShowings* firsts = nullptr);
    /// SpriteGpu::atlas for a resident frame: xyz = atlas origin, w = palette base index.
    glm::uvec4 entry(const VoxelModel& model, int frame) const;
    /// SpriteGpu::brickBase for a resident frame: its first word in brickBuffer().
    std::uint32_t brickBase(const VoxelModel& model, int frame) const;

    /// entry() and brickBase() of every frame of `models`, looked up once for a frame's sprites
    /// (two hash lookups per sprite were a tenth of the near tier's host time at 100,000 tanks).
    struct Placements {
        struct Frame {
            glm::uvec4 atlas{0};
            std::uint32_t brickBase = 0;
            bool present = false;
            bool operator==(const Frame&) const = default;
        };
        std::vector<std::size_t> first; ///< per model index, its frame 0 in `frames`; one past
        std::vector<Frame> frames;
        bool operator==(const Placements&) const = default;
        /// The placement of (model index, frame); throws std::logic_error where that frame is
        /// not resident (update() has not seen a sprite of it), as entry() does.
        const Frame& at(std::size_t model, int frame) const;
    };
    /// Refills `out` (its storage kept) for `models`, indexed as SpriteSetup::model indexes them.
    void placements(const std::vector<std::shared_ptr<VoxelModel>>& models, Placements& out) const;

    VkImageView atlasView() const { return atlas_.view(); }
    VkBuffer paletteBuffer() const { return palettes_.buffer.handle(); }
    VkDeviceSize paletteBytes() const { return palettes_.buffer.size(); }
    VkBuffer brickBuffer() const { return bricks_.buffer.handle(); }
    VkExtent3D atlasExtent() const { return atlas_.extent(); }
    /// Changes whenever the atlas image, the palette or the brick buffer is re-created
    /// (descriptors go stale).
    std::uint64_t generation() const { return generation_; }
    const AtlasPacker& packer() const { return packer_; }
    /// Totals since construction.
    const ResidencyStats& totals() const { return totals_; }

  private:
    struct Resident {
        std::uint64_t version = 0; ///< model version the atlas holds
        std::uint32_t paletteBase = 0;
        std::vector<glm::ivec3> origin;       ///< per frame
        std::vector<std::uint32_t> brickBase; ///< per frame
        std::vector<bool> present;            ///< per frame
    };
    struct Upload {
        const VoxelGrid* grid;
        Box3i box;         ///< in the frame's voxel coordinates
        glm::ivec3 origin; ///< of the frame in the atlas
    };
    /// update()'s first half: places every visible sprite's (model, frame) not yet resident
    /// (palettes and occupancy words into their mirrors) and lists the voxel boxes to copy,
    /// edited frames' dirty boxes included; on an atlas overflow nothing of it stays.
    std::vector<Upload> placeFrames(const std::vector<std::shared_ptr<VoxelModel>>& models,
                                    std::span<const SpriteSetup* const> sprites,
                                    ResidencyStats& stats, FirstShowings* firsts = nullptr);
    /// Its second half: packs `uploads` (and the staged mirrors) into the staging buffer, grows
    /// the atlas when `grow`, records the copies and waits for them.
    void submitUploads(const std::vector<Upload>& uploads, bool grow, ResidencyStats& stats);

    /// A ShaderRead storage buffer of words (the palettes, the brick occupancy) and its host
    /// mirror, which holds every word the buffer holds.
    struct MirroredWords {
        VulkanBuffer buffer;
        std::vector<std::uint32_t> mirror;
        bool staged = false; ///< the device's words wait for a staged copy of the whole mirror
        /// Re-creates the buffer (from `initialBytes`, doubling) when it holds fewer than `words`
        /// words, with the whole mirror in it; true when it did. `waitForReaders` (may be empty)
        /// runs first when an old buffer is replaced.
        bool reserve(VulkanDevice& device, std::size_t words, VkDeviceSize initialBytes,
                     const std::function<void()>& waitForReaders);
        /// Words [first, first + count) of the mirror onto the device: written directly, or
        /// marked for the next update's staged copy (then the whole mirror goes).
        void write(std::size_t first, std::size_t count);
        /// The bytes a staged copy takes now: the whole mirror, or 0 when nothing waits.
        VkDeviceSize stagedBytes() const;
        /// Records the staged copy from `staging` at `offset` (where the mirror is written) and
        /// the barrier that makes it visible to `readers`.
        void recordStagedCopy(VkCommandBuffer cb, const VulkanBuffer& staging, VkDeviceSize offset,
                              VkPipelineStageFlags readers);
    };

    void createAtlas(std::uint32_t depth, VkCommandBuffer cb, bool copyOld);

    VulkanDevice& device_;
    std::function<void()> waitForReaders_;
    AtlasPacker packer_;
    VulkanImage atlas_;
    VulkanImage retired_; ///< the previous atlas while a growth copy is in flight
    MirroredWords palettes_;
    MirroredWords bricks_;
    VulkanBuffer staging_;
    std::unordered_map<std::uint64_t, Resident> residents_; ///< by VoxelModel::uid()
    std::uint32_t nextPaletteSlot_ = 0;
    std::uint64_t generation_ = 0;
    ResidencyStats totals_;
    VkCommandBuffer cb_ = VK_NULL_HANDLE;
};

} // namespace voxtier
