#include "volumetric/voxel_residency.hpp"

#include "core/stopwatch.hpp"

#include <tbb/blocked_range.h>
#include <tbb/parallel_reduce.h>

#include <algorithm>
#include <chrono>
#include <cstring>
#include <limits>
#include <stdexcept>

namespace voxtier {

namespace {

constexpr int kAtlasSide = 512; ///< slice width and height (>= the largest model side, 256)
constexpr std::uint32_t kInitialDepth = 64;
/// The atlas is read by the near fragment shader and by the cell-rate compute pass
/// (shaders/near_cells.comp): uploads wait for both and are made visible to both.
constexpr VkPipelineStageFlags kAtlasReaders =
    VK_PIPELINE_STAGE_FRAGMENT_SHADER_BIT | VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT;

VkDeviceSize roundUp4(VkDeviceSize v) {
    return (v + 3) & ~VkDeviceSize(3);
}

constexpr VkDeviceSize kInitialPaletteBytes = 64 * 256 * sizeof(std::uint32_t);
constexpr VkDeviceSize kInitialBrickBytes = 1 << 16;

/// The least place of a sprite per model and per frame of a model (and of the first sprite whose
/// model or frame is out of range), sorted: sprite k of `sprites` is drawn at place(k), or not at
/// all (VoxelResidency::kNotShown). Found in parallel (at 100,000 sprites the serial walk over
/// every sprite was a cache miss apiece, 5-7 ms on two cores), each task keeping the least place
/// per model and per frame of a model.
template <class Place>
std::vector<std::uint32_t> leastPlaces(const std::vector<std::shared_ptr<VoxelModel>>& models,
                                       std::span<const SpriteSetup* const> sprites, Place place) {
    constexpr std::uint32_t kNone = VoxelResidency::kNotShown;
    // Slot layout: one per model, then one per frame of each model, then one for the first sprite
    // whose model or frame is out of range (left to the serial walk, which names it).
    std::vector<std::uint32_t> frameSlot(models.size() + 1, std::uint32_t(models.size()));
    for (std::size_t m = 0; m < models.size(); ++m)
        frameSlot[m + 1] = frameSlot[m] + std::uint32_t(models[m] ? models[m]->frameCount() : 0);
    const std::size_t slots = frameSlot.back() + 1;
    using Least = std::vector<std::uint32_t>;
    const Least least = tbb::parallel_reduce(
        tbb::blocked_range<std::uint32_t>(0, std::uint32_t(sprites.size()), 256), Least(),
        [&](const auto& r, Least local) {
            if (local.empty()) local.assign(slots, kNone);
            for (std::uint32_t k = r.begin(); k != r.end(); ++k) {
                const std::uint32_t p = place(k);
                if (p == kNone) continue;
                const SpriteSetup* sp = sprites[k];
                if (!sp->visible()) continue;
                const auto m = std::size_t(sp->model);
                if (m >= models.size() || sp->frame < 0 ||
                    frameSlot[m] + std::uint32_t(sp->frame) >= frameSlot[m + 1]) {
                    local[slots - 1] = std::min(local[slots - 1], p);
                    continue;
                }
                local[m] = std::min(local[m], p);
                const std::size_t f = frameSlot[m] + std::size_t(sp->frame);
                local[f] = std::min(local[f], p);
            }
            return local;
        },
        [](Least a, const Least& b) {
            if (a.empty()) return b;
            for (std::size_t i = 0; i < b.size(); ++i) a[i] = std::min(a[i], b[i]);
            return a;
        });
    std::vector<std::uint32_t> firsts;
    for (const std::uint32_t k : least)
        if (k != kNone) firsts.push_back(k);
    std::sort(firsts.begin(), firsts.end());
    firsts.erase(std::unique(firsts.begin(), firsts.end()), firsts.end());
    return firsts;
}

} // namespace

ResidencyStats& ResidencyStats::operator+=(const ResidencyStats& o) {
    bytesUploaded += o.bytesUploaded;
    regions += o.regions;
    fullFrames += o.fullFrames;
    atlasGrowths += o.atlasGrowths;
    milliseconds += o.milliseconds;
    return *this;
}

VoxelResidency::VoxelResidency(VulkanDevice& device, std::function<void()> waitForReaders)
    : device_(device), waitForReaders_(std::move(waitForReaders)),
      packer_(std::min<int>(kAtlasSide, int(device.properties().limits.maxImageDimension3D)),
              std::min<int>(kAtlasSide, int(device.properties().limits.maxImageDimension3D)),
              int(device.properties().limits.maxImageDimension3D)) {
    cb_ = device_.allocateCommandBuffer();
    try {
        // An atlas exists from the start (in the layout the shader reads), so the descriptor set
        // is always complete, even for a frame with nothing to draw.
        VkCommandBufferBeginInfo bi{VK_STRUCTURE_TYPE_COMMAND_BUFFER_BEGIN_INFO};
        bi.flags = VK_COMMAND_BUFFER_USAGE_ONE_TIME_SUBMIT_BIT;
        VK_CHECK(vkBeginCommandBuffer(cb_, &bi));
        createAtlas(kInitialDepth, cb_, false);
        imageBarrier(cb_, atlas_.handle(), VK_IMAGE_ASPECT_COLOR_BIT,
                     VK_IMAGE_LAYOUT_TRANSFER_DST_OPTIMAL, VK_IMAGE_LAYOUT_SHADER_READ_ONLY_OPTIMAL,
                     VK_PIPELINE_STAGE_TRANSFER_BIT, VK_ACCESS_TRANSFER_WRITE_BIT, kAtlasReaders,
                     VK_ACCESS_SHADER_READ_BIT);
        VK_CHECK(vkEndCommandBuffer(cb_));
        device_.submitAndWait(cb_);
        palettes_.reserve(device_, 256, kInitialPaletteBytes, waitForReaders_);
        bricks_.reserve(device_, 1, kInitialBrickBytes, waitForReaders_);
    } catch (...) {
        device_.freeCommandBuffer(cb_);
        throw;
    }
}

VoxelResidency::~VoxelResidency() {
    device_.freeCommandBuffer(cb_);
}

void VoxelResidency::createAtlas(std::uint32_t depth, VkCommandBuffer cb, bool copyOld) {
    VulkanImage fresh(device_, VK_IMAGE_TYPE_3D, VK_FORMAT_R8_UINT,
                      {std::uint32_t(packer_.width()), std::uint32_t(packer_.height()), depth},
                      VK_IMAGE_USAGE_SAMPLED_BIT | VK_IMAGE_USAGE_TRANSFER_DST_BIT |
                          VK_IMAGE_USAGE_TRANSFER_SRC_BIT,
                      VK_IMAGE_ASPECT_COLOR_BIT);
    imageBarrier(cb, fresh.handle(), VK_IMAGE_ASPECT_COLOR_BIT, VK_IMAGE_LAYOUT_UNDEFINED,
                 VK_IMAGE_LAYOUT_TRANSFER_DST_OPTIMAL, VK_PIPELINE_STAGE_TOP_OF_PIPE_BIT, 0,
                 VK_PIPELINE_STAGE_TRANSFER_BIT, VK_ACCESS_TRANSFER_WRITE_BIT);
    if (copyOld) {
        // Growing keeps every block where it was: copy the old atlas into the top of the new one.
        imageBarrier(cb, atlas_.handle(), VK_IMAGE_ASPECT_COLOR_BIT,
                     VK_IMAGE_LAYOUT_SHADER_READ_ONLY_OPTIMAL, VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL,
                     kAtlasReaders, 0, VK_PIPELINE_STAGE_TRANSFER_BIT, VK_ACCESS_TRANSFER_READ_BIT);
        VkImageCopy region{};
        region.srcSubresource = {VK_IMAGE_ASPECT_COLOR_BIT, 0, 0, 1};
        region.dstSubresource = {VK_IMAGE_ASPECT_COLOR_BIT, 0, 0, 1};
        region.extent = atlas_.extent();
        vkCmdCopyImage(cb, atlas_.handle(), VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL, fresh.handle(),
                       VK_IMAGE_LAYOUT_TRANSFER_DST_OPTIMAL, 1, &region);
        // The uploads that follow write into the same image: order them after this copy.
        imageBarrier(cb, fresh.handle(), VK_IMAGE_ASPECT_COLOR_BIT,
                     VK_IMAGE_LAYOUT_TRANSFER_DST_OPTIMAL, VK_IMAGE_LAYOUT_TRANSFER_DST_OPTIMAL,
                     VK_PIPELINE_STAGE_TRANSFER_BIT, VK_ACCESS_TRANSFER_WRITE_BIT,
                     VK_PIPELINE_STAGE_TRANSFER_BIT, VK_ACCESS_TRANSFER_WRITE_BIT);
    }
    retired_ = std::move(atlas_);
    atlas_ = std::move(fresh);
    ++generation_;
}

bool VoxelResidency::MirroredWords::reserve(VulkanDevice& device, std::size_t words,
                                            VkDeviceSize initialBytes,
                                            const std::function<void()>& waitForReaders) {
    const VkDeviceSize need = VkDeviceSize(std::max<std::size_t>(words, 1)) * sizeof(std::uint32_t);
    if (buffer && buffer.size() >= need) return false;
    VkDeviceSize size = buffer ? buffer.size() : initialBytes;
    while (size < need) size *= 2;
    if (buffer && waitForReaders) waitForReaders(); // frames in flight read the old buffer
    buffer =
        VulkanBuffer(device, size, VK_BUFFER_USAGE_STORAGE_BUFFER_BIT, BufferClass::ShaderRead);
    // The whole mirror goes into the new buffer (directly, or staged with the next upload); the
    // tail past it is never read (no sprite's base points there).
    write(0, mirror.size());
    return true;
}

void VoxelResidency::MirroredWords::write(std::size_t first, std::size_t count) {
    if (count == 0) return;
    if (buffer.placement().hostWrite == HostWrite::Direct)
        buffer.write(first * sizeof(std::uint32_t), mirror.data() + first,
                     count * sizeof(std::uint32_t));
    else
        staged = true; // the whole mirror, with the update's copies
}

VkDeviceSize VoxelResidency::MirroredWords::stagedBytes() const {
    return staged ? mirror.size() * sizeof(std::uint32_t) : 0;
}

void VoxelResidency::MirroredWords::recordStagedCopy(VkCommandBuffer cb,
                                                     const VulkanBuffer& staging,
                                                     VkDeviceSize offset,
                                                     VkPipelineStageFlags readers) {
    const VkDeviceSize bytes = stagedBytes();
    if (bytes == 0) return;
    std::memcpy(static_cast<std::uint8_t*>(staging.mapped()) + offset, mirror.data(),
                std::size_t(bytes));
    const VkBufferCopy copy{offset, 0, bytes};
    vkCmdCopyBuffer(cb, staging.handle(), buffer.handle(), 1, &copy);
    bufferBarrier(cb, buffer.handle(), VK_PIPELINE_STAGE_TRANSFER_BIT, VK_ACCESS_TRANSFER_WRITE_BIT,
                  readers, VK_ACCESS_SHADER_READ_BIT);
    staged = false;
}

std::uint32_t VoxelResidency::brickBase(const VoxelModel& model, int frame) const {
    const auto it = residents_.find(model.uid());
    if (it == residents_.end() || frame < 0 || std::size_t(frame) >= it->second.present.size() ||
        !it->second.present[std::size_t(frame)])
        throw std::logic_error("VoxelResidency::brickBase: frame not resident (call update first)");
    return it->second.brickBase[std::size_t(frame)];
}

void VoxelResidency::placements(const std::vector<std::shared_ptr<VoxelModel>>& models,
                                Placements& out) const {
    out.first.assign(1, 0);
    out.frames.clear();
    for (const std::shared_ptr<VoxelModel>& model : models) {
        const int frames = model ? model->frameCount() : 0;
        const auto it = model ? residents_.find(model->uid()) : residents_.end();
        for (int f = 0; f < frames; ++f) {
            Placements::Frame p;
            if (it != residents_.end() && std::size_t(f) < it->second.present.size() &&
                it->second.present[std::size_t(f)]) {
                const glm::ivec3 o = it->second.origin[std::size_t(f)];
                p = {{std::uint32_t(o.x), std::uint32_t(o.y), std::uint32_t(o.z),
                      it->second.paletteBase},
                     it->second.brickBase[std::size_t(f)],
                     true};
            }
            out.frames.push_back(p);
        }
        out.first.push_back(out.frames.size());
    }
}

const VoxelResidency::Placements::Frame& VoxelResidency::Placements::at(std::size_t model,
                                                                        int frame) const {
    if (model + 1 >= first.size() || frame < 0 ||
        std::size_t(frame) >= first[model + 1] - first[model] ||
        !frames[first[model] + std::size_t(frame)].present)
        throw std::logic_error(
            "VoxelResidency::placements: frame not resident (call update first)");
    return frames[first[model] + std::size_t(frame)];
}

glm::uvec4 VoxelResidency::entry(const VoxelModel& model, int frame) const {
    const auto it = residents_.find(model.uid());
    if (it == residents_.end() || frame < 0 || std::size_t(frame) >= it->second.present.size() ||
        !it->second.present[std::size_t(frame)])
        throw std::logic_error("VoxelResidency::entry: frame not resident (call update first)");
    const glm::ivec3 o = it->second.origin[std::size_t(frame)];
    return {std::uint32_t(o.x), std::uint32_t(o.y), std::uint32_t(o.z), it->second.paletteBase};
}

ResidencyStats VoxelResidency::update(const std::vector<std::shared_ptr<VoxelModel>>& models,
                                      std::span<const SpriteSetup* const> sprites,
                                      FirstShowings* firsts) {
    const auto t0 = std::chrono::steady_clock::now();
    ResidencyStats stats;
    const std::vector<Upload> uploads = placeFrames(models, sprites, stats, firsts);
    const bool grow = std::uint32_t(packer_.usedDepth()) > atlas_.extent().depth;
    if (uploads.empty() && !grow && !palettes_.staged && !bricks_.staged) return stats;
    submitUploads(uploads, grow, stats);
    stats.milliseconds = msSince(t0);
    totals_ += stats;
    return stats;
}

std::vector<std::uint32_t>
VoxelResidency::firstShowingsAt(const std::vector<std::shared_ptr<VoxelModel>>& models,
                                std::span<const SpriteSetup* const> sprites,
                                std::span<const std::uint32_t> places) {
    if (places.size() != sprites.size())
        throw std::invalid_argument("firstShowingsAt: one place per sprite");
    return leastPlaces(models, sprites, [&](std::uint32_t k) { return places[k]; });
}

std::vector<VoxelResidency::Upload>
VoxelResidency::placeFrames(const std::vector<std::shared_ptr<VoxelModel>>& models,
                            std::span<const SpriteSetup* const> sprites, ResidencyStats& stats,
                            FirstShowings* firsts) {
    FirstShowings found;
    FirstShowings& shown = firsts ? *firsts : found;
    if (shown.valid && !shown.firsts.empty() && shown.firsts.back() >= sprites.size())
        shown.valid = false; // not these sprites' (firsts ascend)
    if (!shown.valid)
        shown = {true, leastPlaces(models, sprites, [](std::uint32_t k) { return k; })};
    std::vector<Upload> uploads;
    // Undo list: if placing a block fails (atlas full), nothing recorded here was uploaded.
    std::vector<std::pair<Resident*, int>> placed;
    std::vector<std::pair<Resident*, std::uint64_t>> synced;
    try {
        for (const std::uint32_t k : shown.firsts) {
            const SpriteSetup* sp = sprites[k];
            const VoxelModel& model = *models.at(std::size_t(sp->model));
            auto [it, inserted] = residents_.try_emplace(model.uid());
            Resident& r = it->second;
            if (inserted) {
                r.version = model.version();
                r.paletteBase = nextPaletteSlot_++ * 256u;
                r.origin.assign(std::size_t(model.frameCount()), glm::ivec3(0));
                r.brickBase.assign(std::size_t(model.frameCount()), 0u);
                r.present.assign(std::size_t(model.frameCount()), false);
                palettes_.mirror.insert(palettes_.mirror.end(), model.palette().colors.begin(),
                                        model.palette().colors.end());
                if (palettes_.reserve(device_, palettes_.mirror.size(), kInitialPaletteBytes,
                                      waitForReaders_))
                    ++generation_; // the whole mirror written
                else
                    palettes_.write(r.paletteBase, 256);
            } else if (r.version != model.version()) {
                // Edited since the last upload: each resident frame re-sends only its dirty box.
                // Its occupancy words are rewritten in place, possibly straight into memory a
                // frame in flight reads: that frame must finish first (edits are rare).
                if (waitForReaders_) waitForReaders_();
                synced.emplace_back(&r, r.version);
                for (int f = 0; f < model.frameCount(); ++f) {
                    if (!r.present[std::size_t(f)]) continue;
                    const VoxelGrid& grid = model.frame(f);
                    const Box3i whole{glm::ivec3(0), grid.dims()};
                    const std::optional<Box3i> dirty = model.dirtySince(r.version, f);
                    const Box3i box = dirty ? dirty->intersected(whole) : whole;
                    if (box.empty()) continue;
                    uploads.push_back({&grid, box, r.origin[std::size_t(f)]});
                    // Its occupancy, whole: a few KiB at most (a region bit may change with
                    // any brick of the region).
                    const std::span<const std::uint32_t> words = model.bricks(f).words();
                    const std::uint32_t base = r.brickBase[std::size_t(f)];
                    std::copy(words.begin(), words.end(), bricks_.mirror.begin() + base);
                    bricks_.write(base, words.size());
                    stats.fullFrames += box == whole;
                }
                r.version = model.version();
            }
            const std::size_t f = std::size_t(sp->frame);
            if (!r.present[f]) {
                const VoxelGrid& grid = model.frame(sp->frame);
                r.origin[f] = packer_.allocate(grid.dims());
                r.present[f] = true;
                // Its brick occupancy, whole, after the mirror's words (left there, unused, when
                // a later placement fails).
                const std::span<const std::uint32_t> words = model.bricks(sp->frame).words();
                r.brickBase[f] = std::uint32_t(bricks_.mirror.size());
                bricks_.mirror.insert(bricks_.mirror.end(), words.begin(), words.end());
                if (bricks_.reserve(device_, bricks_.mirror.size(), kInitialBrickBytes,
                                    waitForReaders_))
                    ++generation_; // the whole mirror written
                else
                    bricks_.write(r.brickBase[f], words.size());
                placed.emplace_back(&r, sp->frame);
                uploads.push_back({&grid, {glm::ivec3(0), grid.dims()}, r.origin[f]});
                ++stats.fullFrames;
            }
        }
    } catch (const std::length_error& e) {
        for (auto [r, f] : placed) r->present[std::size_t(f)] = false;
        for (auto [r, v] : synced) r->version = v;
        throw VulkanError(std::string("near tier: ") + e.what());
    }
    return uploads;
}

void VoxelResidency::submitUploads(const std::vector<Upload>& uploads, bool grow,
                                   ResidencyStats& stats) {
    // Pack every region tightly into one staging buffer (rows of the box, x fastest), then the
    // palettes and the brick words where the device's buffers are staged.
    VkDeviceSize total = 0;
    for (const Upload& u : uploads) total = roundUp4(total + VkDeviceSize(u.box.volume()));
    const VkDeviceSize paletteOffset = total;
    total += palettes_.stagedBytes();
    const VkDeviceSize brickOffset = total;
    total += bricks_.stagedBytes();
    if (!staging_ || staging_.size() < total) {
        VkDeviceSize size = 1 << 16;
        while (size < total) size *= 2;
        staging_ = VulkanBuffer(device_, size, 0, BufferClass::Staging);
    }
    std::vector<VkBufferImageCopy> regions;
    regions.reserve(uploads.size());
    VkDeviceSize offset = 0;
    auto* dst = static_cast<std::uint8_t*>(staging_.mapped());
    for (const Upload& u : uploads) {
        const glm::ivec3 size = u.box.max - u.box.min;
        VkBufferImageCopy region{};
        region.bufferOffset = offset;
        region.imageSubresource = {VK_IMAGE_ASPECT_COLOR_BIT, 0, 0, 1};
        region.imageOffset = {u.origin.x + u.box.min.x, u.origin.y + u.box.min.y,
                              u.origin.z + u.box.min.z};
        region.imageExtent = {std::uint32_t(size.x), std::uint32_t(size.y), std::uint32_t(size.z)};
        regions.push_back(region);
        std::uint8_t* out = dst + offset;
        for (int z = u.box.min.z; z < u.box.max.z; ++z)
            for (int y = u.box.min.y; y < u.box.max.y; ++y) {
                std::memcpy(out, u.grid->data().data() + u.grid->linearIndex({u.box.min.x, y, z}),
                            std::size_t(size.x));
                out += size.x;
            }
        stats.bytesUploaded += std::uint64_t(u.box.volume());
        offset = roundUp4(offset + VkDeviceSize(u.box.volume()));
    }
    stats.regions = regions.size();

    VkCommandBufferBeginInfo bi{VK_STRUCTURE_TYPE_COMMAND_BUFFER_BEGIN_INFO};
    bi.flags = VK_COMMAND_BUFFER_USAGE_ONE_TIME_SUBMIT_BIT;
    VK_CHECK(vkResetCommandBuffer(cb_, 0));
    VK_CHECK(vkBeginCommandBuffer(cb_, &bi));
    if (grow) {
        // The old atlas is destroyed once the copy is done: frames in flight read it.
        if (waitForReaders_) waitForReaders_();
        std::uint32_t depth = atlas_.extent().depth;
        while (depth < std::uint32_t(packer_.usedDepth())) depth *= 2;
        depth = std::min(depth, std::uint32_t(packer_.maxDepth()));
        createAtlas(depth, cb_, true);
        ++stats.atlasGrowths;
    } else {
        imageBarrier(cb_, atlas_.handle(), VK_IMAGE_ASPECT_COLOR_BIT,
                     VK_IMAGE_LAYOUT_SHADER_READ_ONLY_OPTIMAL, VK_IMAGE_LAYOUT_TRANSFER_DST_OPTIMAL,
                     kAtlasReaders, 0, VK_PIPELINE_STAGE_TRANSFER_BIT,
                     VK_ACCESS_TRANSFER_WRITE_BIT);
    }
    if (!regions.empty())
        vkCmdCopyBufferToImage(cb_, staging_.handle(), atlas_.handle(),
                               VK_IMAGE_LAYOUT_TRANSFER_DST_OPTIMAL, std::uint32_t(regions.size()),
                               regions.data());
    palettes_.recordStagedCopy(cb_, staging_, paletteOffset, kAtlasReaders);
    bricks_.recordStagedCopy(cb_, staging_, brickOffset, kAtlasReaders);
    staging_.flush(0, total);
    imageBarrier(cb_, atlas_.handle(), VK_IMAGE_ASPECT_COLOR_BIT,
                 VK_IMAGE_LAYOUT_TRANSFER_DST_OPTIMAL, VK_IMAGE_LAYOUT_SHADER_READ_ONLY_OPTIMAL,
                 VK_PIPELINE_STAGE_TRANSFER_BIT, VK_ACCESS_TRANSFER_WRITE_BIT, kAtlasReaders,
                 VK_ACCESS_SHADER_READ_BIT);
    VK_CHECK(vkEndCommandBuffer(cb_));
    device_.submitAndWait(cb_);
    retired_.reset();
}

} // namespace voxtier
