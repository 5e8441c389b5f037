#pragma once
// Voxel models: dense uint8 palette-index grids (one per animation frame) sharing one
// 256-entry palette, with an edit API that bumps a version counter and logs dirty boxes so
// every consumer (GPU residency, snapshot cache) can ask "what changed since version v?".
#include "core/sprite_kernel.h"

#include <glm/glm.hpp>

#include <array>
#include <atomic>
#include <cstdint>
#include <optional>
#include <span>
#include <string>
#include <vector>

namespace voxtier {

/// Half-open integer box [min, max). Empty when any max <= min.
struct Box3i {
    glm::ivec3 min{0}, max{0};

    bool empty() const { return max.x <= min.x || max.y <= min.y || max.z <= min.z; }
    long long volume() const {
        return empty() ? 0 : 1LL * (max.x - min.x) * (max.y - min.y) * (max.z - min.z);
    }
    bool contains(glm::ivec3 p) const {
        return p.x >= min.x && p.y >= min.y && p.z >= min.z && p.x < max.x && p.y < max.y &&
               p.z < max.z;
    }
    /// Smallest box holding both; the empty box is the identity.
    Box3i united(const Box3i& o) const;
    Box3i intersected(const Box3i& o) const;
    Box3i expanded(int by) const { return {min - by, max + by}; }
    bool operator==(const Box3i&) const = default;
};

/// Packed RGBA8, R in the lowest byte (the byte order of an RGBA8 image in memory).
using Rgba8 = std::uint32_t;
constexpr Rgba8 packRgba(unsigned r, unsigned g, unsigned b, unsigned a = 255) {
    return (r & 255u) | (g & 255u) << 8 | (b & 255u) << 16 | (a & 255u) << 24;
}
constexpr unsigned channel(Rgba8 c, int i) {
    return (c >> (8 * i)) & 255u;
}

/// 256 colours; entry 0 is "empty" and never drawn (palette index semantics of .vox).
struct Palette {
    std::array<Rgba8, 256> colors{};
    bool operator==(const Palette&) const = default;
};

/// MagicaVoxel's default palette (used when a .vox file has no RGBA chunk).
const Palette& magicaVoxelDefaultPalette();

/// One dense grid: dims up to Limits::kMaxModelDim per axis, x fastest, then y, then z
/// (voxel space is Z-up, CONTRACT.md §2). Value 0 = empty, 1..255 = palette index.
class VoxelGrid {
  public:
    VoxelGrid() = default;
    /// Throws InputError (file = `source`, field "size") for dims outside 1..256.
    explicit VoxelGrid(glm::ivec3 dims, const std::string& source = "");

    glm::ivec3 dims() const { return dims_; }
    std::size_t linearIndex(glm::ivec3 p) const {
        return std::size_t(p.x) +
               std::size_t(dims_.x) * (std::size_t(p.y) + std::size_t(dims_.y) * std::size_t(p.z));
    }
    std::uint8_t at(glm::ivec3 p) const { return data_[linearIndex(p)]; }
    /// Out-of-bounds reads are empty (convenient for neighbour tests).
    std::uint8_t atOrEmpty(glm::ivec3 p) const {
        return (p.x < 0 || p.y < 0 || p.z < 0 || p.x >= dims_.x || p.y >= dims_.y || p.z >= dims_.z)
                   ? 0
                   : at(p);
    }
    void set(glm::ivec3 p, std::uint8_t v) { data_[linearIndex(p)] = v; }
    const std::vector<std::uint8_t>& data() const { return data_; }
    std::vector<std::uint8_t>& data() { return data_; }

    std::size_t solidCount() const;
    /// Bounds of the non-empty voxels (empty box when the grid is empty).
    Box3i contentBounds() const;

  private:
    glm::ivec3 dims_{0};
    std::vector<std::uint8_t> data_;
};

/// The conservative occupancy of one grid that the kernel skips empty space with
/// (core/sprite_kernel.h): one bit per brick (kernel::VT_BRICK^3 voxels), then one per region
/// (kernel::VT_REGION^3 voxels), each level numbered by vtLevelIndex over vtLevelDims, 32 to a
/// word. Contract: a box's bit is clear only when every voxel of it is empty; the skip is exact
/// under that alone. It is kept tight as well (set exactly where a box holds a non-empty voxel)
/// through every edit of a VoxelModel.
class BrickOccupancy {
  public:
    BrickOccupancy() = default;
    /// The occupancy of `grid`, tight.
    explicit BrickOccupancy(const VoxelGrid& grid);

    /// Size in boxes of the level with `shift` (kernel::VT_BRICK_SHIFT or VT_REGION_SHIFT).
    glm::ivec3 dims(int shift) const { return kernel::vtLevelDims(voxelDims_, shift); }
    /// Whether box `box` of that level is marked occupied.
    bool occupied(int shift, glm::ivec3 box) const;
    /// Both levels' words as the kernel reads them (vtFetchBrickWord).
    std::span<const std::uint32_t> words() const { return words_; }
    /// Whether marching over the occupancy pays on this grid (SpriteGpu::skipEmpty): the empty
    /// bricks' share times the mean side, about the cells a ray walks through empty bricks, is
    /// at least kWorthSkippingCells (docs/decisions/empty-space-skipping.md has the figures).
    bool worthSkipping() const;
    static constexpr int kWorthSkippingCells = 24;

    /// After non-empty voxels were written into `box`: marks its bricks and regions occupied.
    void markOccupied(Box3i box);
    /// After voxels of `box` were cleared (or anything else written there): recomputes its
    /// bricks from `grid` and its regions from the bricks.
    void refresh(const VoxelGrid& grid, Box3i box);

  private:
    /// The boxes of the level with `shift` that hold a voxel of `box` (clipped to the grid).
    Box3i boxesOf(int shift, Box3i box) const;
    void set(int shift, glm::ivec3 box, bool occupied);
    std::uint32_t base(int shift) const {
        return shift == kernel::VT_BRICK_SHIFT ? 0u : kernel::vtBrickWords(voxelDims_);
    }

    glm::ivec3 voxelDims_{0};
    std::vector<std::uint32_t> words_;
    std::uint64_t occupiedBricks_ = 0;
};

/// One edit, as recorded in the model's log: the model version it produced and the voxels it
/// may have changed.
struct EditRecord {
    std::uint64_t version;
    int frame;
    Box3i box;
};

/// A model: a name, one palette, one or more frames (animation), and a version that every
/// edit bumps. Not thread-safe for concurrent edits of the same model; different models are
/// independent.
class VoxelModel {
  public:
    VoxelModel();
    VoxelModel(std::string name, Palette palette, std::vector<VoxelGrid> frames);

    /// Process-unique id (never reused), the cache's key for this model.
    std::uint64_t uid() const { return uid_; }
    const std::string& name() const { return name_; }
    void setName(std::string n) { name_ = std::move(n); }
    const Palette& palette() const { return palette_; }

    int frameCount() const { return int(frames_.size()); }
    const VoxelGrid& frame(int f) const { return frames_.at(std::size_t(f)); }
    /// The brick occupancy of frame `f`, kept tight through every edit.
    const BrickOccupancy& bricks(int f) const { return bricks_.at(std::size_t(f)); }
    /// Animation wrap: frame index `f` modulo the frame count (negative wraps too).
    int wrapFrame(long long f) const;

    /// Monotonic; starts at 1 and increases by one per edit call that changed anything.
    std::uint64_t version() const { return version_; }

    // Edits (CONTRACT.md §4 invalidation). Coordinates are clipped to the grid; an edit that
    // changes no voxel does not bump the version. Returns true when something changed.
    bool setVoxel(int frame, glm::ivec3 p, std::uint8_t index);
    bool fillBox(int frame, Box3i box, std::uint8_t index);
    bool clearBox(int frame, Box3i box) { return fillBox(frame, box, 0); }

    /// Union of the boxes changed in `frame` after `sinceVersion` (empty box: nothing changed).
    /// nullopt when the log no longer reaches back that far: treat as "everything changed".
    std::optional<Box3i> dirtySince(std::uint64_t sinceVersion, int frame) const;
    /// True when any frame changed after `sinceVersion` (or the log cannot tell).
    bool changedSince(std::uint64_t sinceVersion) const;

  private:
    void record(int frame, Box3i box);

    std::uint64_t uid_;
    std::string name_;
    Palette palette_;
    std::vector<VoxelGrid> frames_;
    std::vector<BrickOccupancy> bricks_; ///< per frame
    std::uint64_t version_ = 1;
    std::vector<EditRecord> log_; ///< newest last, bounded by kMaxLog
    std::uint64_t logFloor_ = 1;  ///< versions <= logFloor_ are not in the log any more
    static constexpr std::size_t kMaxLog = 4096;
};

} // namespace voxtier
