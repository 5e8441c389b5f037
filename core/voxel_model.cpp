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

namespace {
std::atomic<std::uint64_t> nextModelUid{1};
}

VoxelModel::VoxelModel() : uid_(nextModelUid++) {}

VoxelModel::VoxelModel(std::string name, Palette palette, std::vector<VoxelGrid> frames)
    : uid_(nextModelUid++), name_(std::move(name)), palette_(palette), frames_(std::move(frames)) {}

int VoxelModel::wrapFrame(long long f) const {
    const long long n = std::max<long long>(1, frameCount());
    return int(((f % n) + n) % n);
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
