#include "core/voxel_model.hpp"

#include "core/error.hpp"

#include <algorithm>

namespace voxtier {

Box3i Box3i::united(const Box3i& o) const {
    if (empty()) return o;
    if (o.empty()) return *this;
    return {glm::min(min, o.min), glm::max(max, o.max)};
}

Box3i Box3i::intersected(const Box3i& o) const {
    Box3i r{glm::max(min, o.min), glm::min(max, o.max)};
    return r.empty() ? Box3i{} : r;
}

const Palette& magicaVoxelDefaultPalette() {
    // MagicaVoxel's default palette, from the format description: index 1..215 walk the
    // 6x6x6 colour cube from white down (blue fastest, black skipped), then 10-step ramps of
    // red, green, blue and grey (0xee..0x11, skipping multiples of 0x33 already in the cube).
    static const Palette palette = [] {
        Palette p;
        const unsigned cube[6] = {0xff, 0xcc, 0x99, 0x66, 0x33, 0x00};
        const unsigned ramp[10] = {0xee, 0xdd, 0xbb, 0xaa, 0x88, 0x77, 0x55, 0x44, 0x22, 0x11};
        int i = 1;
        for (unsigned r : cube)
            for (unsigned g : cube)
                for (unsigned b : cube)
                    if (r | g | b) p.colors[std::size_t(i++)] = packRgba(r, g, b);
        for (int channelIndex = 0; channelIndex < 3; ++channelIndex)
            for (unsigned v : ramp)
                p.colors[std::size_t(i++)] =
                    packRgba(channelIndex == 0 ? v : 0, channelIndex == 1 ? v : 0,
                             channelIndex == 2 ? v : 0);
        for (unsigned v : ramp) p.colors[std::size_t(i++)] = packRgba(v, v, v);
        return p;
    }();
    return palette;
}

VoxelGrid::VoxelGrid(glm::ivec3 dims, const std::string& source) : dims_(dims) {
    for (int a = 0; a < 3; ++a)
        if (dims[a] < 1 || dims[a] > Limits::kMaxModelDim)
            throw InputError(source, "size",
                             "model size " + std::to_string(dims.x) + "x" + std::to_string(dims.y) +
                                 "x" + std::to_string(dims.z) + " outside 1.." +
                                 std::to_string(Limits::kMaxModelDim) + " per axis");
    data_.assign(std::size_t(dims.x) * std::size_t(dims.y) * std::size_t(dims.z), 0);
}

std::size_t VoxelGrid::solidCount() const {
    return std::size_t(
        std::count_if(data_.begin(), data_.end(), [](std::uint8_t v) { return v != 0; }));
}

Box3i VoxelGrid::contentBounds() const {
    Box3i b;
    for (int z = 0; z < dims_.z; ++z)
        for (int y = 0; y < dims_.y; ++y) {
            const std::uint8_t* row = &data_[linearIndex({0, y, z})];
            for (int x = 0; x < dims_.x; ++x)
                if (row[x]) b = b.united({{x, y, z}, {x + 1, y + 1, z + 1}});
        }
    return b;
}

BrickOccupancy::BrickOccupancy(const VoxelGrid& grid) : voxelDims_(grid.dims()) {
    const glm::ivec3 regions = dims(kernel::VT_REGION_SHIFT);
    words_.assign(
        kernel::vtBrickWords(voxelDims_) +
            (std::size_t(regions.x) * std::size_t(regions.y) * std::size_t(regions.z) + 31) / 32,
        0u);
    refresh(grid, {glm::ivec3(0), grid.dims()});
}

bool BrickOccupancy::occupied(int shift, glm::ivec3 box) const {
    const std::uint32_t i = kernel::vtLevelIndex(dims(shift), box);
    return (words_[base(shift) + (i >> 5)] >> (i & 31u) & 1u) != 0;
}

Box3i BrickOccupancy::boxesOf(int shift, Box3i box) const {
    const Box3i clipped = box.intersected({glm::ivec3(0), voxelDims_});
    if (clipped.empty()) return {};
    return {clipped.min >> shift, ((clipped.max - 1) >> shift) + 1};
}

void BrickOccupancy::set(int shift, glm::ivec3 box, bool occupied) {
    const std::uint32_t i = kernel::vtLevelIndex(dims(shift), box);
    std::uint32_t& word = words_[base(shift) + (i >> 5)];
    const std::uint32_t bit = 1u << (i & 31u);
    if (shift == kernel::VT_BRICK_SHIFT && ((word & bit) != 0) != occupied)
        occupied ? ++occupiedBricks_ : --occupiedBricks_;
    word = occupied ? word | bit : word & ~bit;
}

bool BrickOccupancy::worthSkipping() const {
    const glm::ivec3 b = dims(kernel::VT_BRICK_SHIFT);
    const std::uint64_t bricks = std::uint64_t(b.x) * std::uint64_t(b.y) * std::uint64_t(b.z);
    // (empty / bricks) * (sx + sy + sz) / 3 >= kWorthSkippingCells, in integers.
    return (bricks - occupiedBricks_) * std::uint64_t(voxelDims_.x + voxelDims_.y + voxelDims_.z) >=
           3 * std::uint64_t(kWorthSkippingCells) * bricks;
}

void BrickOccupancy::markOccupied(Box3i box) {
    for (int shift : {kernel::VT_BRICK_SHIFT, kernel::VT_REGION_SHIFT}) {
        const Box3i b = boxesOf(shift, box);
        for (int z = b.min.z; z < b.max.z; ++z)
            for (int y = b.min.y; y < b.max.y; ++y)
                for (int x = b.min.x; x < b.max.x; ++x) set(shift, {x, y, z}, true);
    }
}

void BrickOccupancy::refresh(const VoxelGrid& grid, Box3i box) {
    constexpr int kBrick = kernel::VT_BRICK_SHIFT, kRegion = kernel::VT_REGION_SHIFT;
    // The bricks: cleared, then one pass over their voxels, row by row; a row moves on to the
    // next brick at its first non-empty voxel in this one.
    const Box3i b = boxesOf(kBrick, box);
    for (int z = b.min.z; z < b.max.z; ++z)
        for (int y = b.min.y; y < b.max.y; ++y)
            for (int x = b.min.x; x < b.max.x; ++x) set(kBrick, {x, y, z}, false);
    const Box3i voxels =
        Box3i{b.min << kBrick, b.max << kBrick}.intersected({glm::ivec3(0), voxelDims_});
    for (int z = voxels.min.z; z < voxels.max.z; ++z)
        for (int y = voxels.min.y; y < voxels.max.y; ++y) {
            const std::uint8_t* row = &grid.data()[grid.linearIndex({0, y, z})];
            for (int x = voxels.min.x; x < voxels.max.x; ++x)
                if (row[x] != 0) {
                    set(kBrick, glm::ivec3(x, y, z) >> kBrick, true);
                    x |= kernel::VT_BRICK - 1;
                }
        }
    // The regions holding those bricks, from their bricks.
    const Box3i r = boxesOf(kRegion, box);
    const glm::ivec3 bricks = dims(kBrick);
    for (int z = r.min.z; z < r.max.z; ++z)
        for (int y = r.min.y; y < r.max.y; ++y)
            for (int x = r.min.x; x < r.max.x; ++x) {
                const glm::ivec3 region{x, y, z};
                const glm::ivec3 lo = region << (kRegion - kBrick);
                const glm::ivec3 hi = glm::min(lo + (1 << (kRegion - kBrick)), bricks);
                bool any = false;
                for (int bz = lo.z; bz < hi.z && !any; ++bz)
                    for (int by = lo.y; by < hi.y && !any; ++by)
                        for (int bx = lo.x; bx < hi.x && !any; ++bx)
                            any = occupied(kBrick, {bx, by, bz});
                set(kRegion, region, any);
            }
}

namespace {
std::atomic<std::uint64_t> nextModelUid{1};
}

VoxelModel::VoxelModel() : uid_(nextModelUid++) {}

VoxelModel::VoxelModel(std::string name, Palette palette, std::vector<VoxelGrid> frames)
    : uid_(nextModelUid++), name_(std::move(name)), palette_(palette), frames_(std::move(frames)) {
    bricks_.reserve(frames_.size());
    for (const VoxelGrid& g : frames_) bricks_.emplace_back(g);
}

int VoxelModel::wrapFrame(long long f) const {
    const long long n = std::max<long long>(1, frameCount());
    // One division where f is not negative (every frame of a forward animation): the sprite
    // store asks this of every entity each update.
    return int(f >= 0 ? f % n : ((f % n) + n) % n);
}

bool VoxelModel::setVoxel(int frame, glm::ivec3 p, std::uint8_t index) {
    return fillBox(frame, {p, p + 1}, index);
}

bool VoxelModel::fillBox(int frame, Box3i box, std::uint8_t index) {
    VoxelGrid& g = frames_.at(std::size_t(frame));
    const Box3i clipped = box.intersected({{0, 0, 0}, g.dims()});
    if (clipped.empty()) return false;
    Box3i changed;
    for (int z = clipped.min.z; z < clipped.max.z; ++z)
        for (int y = clipped.min.y; y < clipped.max.y; ++y)
            for (int x = clipped.min.x; x < clipped.max.x; ++x) {
                const glm::ivec3 p{x, y, z};
                if (g.at(p) != index) {
                    g.set(p, index);
                    changed = changed.united({p, p + 1});
                }
            }
    if (changed.empty()) return false;
    // The occupancy stays tight: a fill occupies its bricks, a clear may empty some.
    BrickOccupancy& bricks = bricks_[std::size_t(frame)];
    if (index != 0)
        bricks.markOccupied(changed);
    else
        bricks.refresh(g, changed);
    record(frame, changed);
    return true;
}

void VoxelModel::record(int frame, Box3i box) {
    ++version_;
    log_.push_back({version_, frame, box});
    if (log_.size() > kMaxLog) {
        const std::size_t drop = log_.size() - kMaxLog / 2;
        logFloor_ = log_[drop - 1].version;
        log_.erase(log_.begin(), log_.begin() + std::ptrdiff_t(drop));
    }
}

std::optional<Box3i> VoxelModel::dirtySince(std::uint64_t sinceVersion, int frame) const {
    if (sinceVersion >= version_) return Box3i{};
    if (sinceVersion < logFloor_) return std::nullopt;
    Box3i box;
    for (auto it = log_.rbegin(); it != log_.rend() && it->version > sinceVersion; ++it)
        if (it->frame == frame) box = box.united(it->box);
    return box;
}

bool VoxelModel::changedSince(std::uint64_t sinceVersion) const {
    return sinceVersion < version_;
}

} // namespace voxtier
