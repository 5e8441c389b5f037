#include "impostor_cache/far_pass.hpp"

#include "core/key_sort.hpp"
#include "core/sprite_kernel.h"
#include "core/stopwatch.hpp"
#include "impostor_cache/far_residency.hpp"
#include "impostor_cache/shaders/far_shared.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/parallel_reduce.h>

#include <algorithm>
#include <array>
#include <bit>
#include <cmath>
#include <functional>
#include <unordered_map>
#include <unordered_set>
#include <vector>

// SPIR-V generated at build time by glslangValidator (impostor_cache/CMakeLists.txt).
#include "shaders/far_blit_coarse_comp.h"
#include "shaders/far_blit_fine_comp.h"
#include "shaders/far_resolve_comp.h"
#include "shaders/far_splat_comp.h"

namespace voxtier {

namespace {
/// How many instances ahead the records' loop asks for the lines it will read.
constexpr std::size_t kReadAhead = 8;

/// A far sprite's place in the order the far pass draws in: ascending keys are the depth-and-id
/// rule's order (winsDepthTest), nearest first (the greater reversed-Z depth), equal depths by
/// ascending entity id. Floats compared as numbers: -0 is 0, and a NaN depth, which wins no
/// pixel, goes last.
std::uint64_t farOrderKey(float depth, std::uint32_t entityId) {
    std::uint32_t ordered; // ascending with the depth
    if (std::isnan(depth)) {
        ordered = 0;
    } else {
        const std::uint32_t bits = std::bit_cast<std::uint32_t>(depth == 0.0f ? 0.0f : depth);
        ordered = (bits & 0x80000000u) ? ~bits : bits | 0x80000000u;
    }
    return (std::uint64_t(~ordered) << 32) | entityId;
}
} // namespace

struct FarPass::Impl {
    GpuFrames& frames;
    VulkanDevice& device;
    FarTiles tiles;
    int side; ///< pixels per side of a tile
    FarResidency residency;
    VkDescriptorSetLayout setLayout = VK_NULL_HANDLE;
    VkPipelineLayout pipelineLayout = VK_NULL_HANDLE;
    VkDescriptorPool descriptorPool = VK_NULL_HANDLE;
    VkPipeline pipeline = VK_NULL_HANDLE;
    /// FarTiles::Sprites: the resolve after the splat (`pipeline`).
    VkPipeline resolvePipeline = VK_NULL_HANDLE;

    /// What a slot's instance buffer holds (writeInstances): per place, the instance whose
    /// record it is, as of update `asOf` of the sprite store `store` (0: nothing known).
    struct KeptRecords {
        static constexpr std::uint32_t kNoEntity = SpriteHistory::kNoEntity;
        /// Everything a record is made from besides its sprite (and the sprite's rectangle in
        /// an image of the slot's size): the entity (kNoEntity: a copy of a sprite, a
        /// cross-fade's), and the record's fields that are not the sprite's, as values (not the
        /// snapshot's address, which a later snapshot may take): the snapshot's device offset,
        /// size and first cell, the palette's place, the cell map's bits.
        struct Place {
            std::uint32_t entity = kNoEntity;
            glm::uvec4 snap{0u};
            std::int32_t firstCellJ = 0, palette = 0;
            std::array<std::uint64_t, 6> map{};
            bool operator==(const Place&) const = default;
        };
        std::uint64_t store = 0, asOf = 0;
        VkBuffer buffer = VK_NULL_HANDLE;
        int width = 0, height = 0;
        std::vector<Place> places;
    };
    /// Per frame in flight: what the host writes for a frame, and its descriptor set.
    struct Slot {
        VulkanBuffer instances, palettes, tiles, tileList;
        /// FarTiles::Sprites: a word per pixel, the splat's winner (written on the device only).
        VulkanBuffer winners;
        VkDescriptorSet set = VK_NULL_HANDLE;
        KeptRecords kept;
    };
    std::vector<Slot> slots;

    // The frame being recorded (host scratch, reused from frame to frame).
    std::vector<std::uint32_t> palettes, list;
    /// Per run of drawn instances and tile: its entries, then where they start (prepare's
    /// binning).
    std::vector<std::uint32_t> runOffsets;
    std::vector<far_gpu::FarTile> tileRecords;
    std::unordered_map<const Palette*, std::uint32_t> paletteBase;
    /// Per chunk of instances (prepare): its drawn instances' distinct palettes in the order
    /// shown, and the drawn instances of the chunks before it.
    std::vector<std::vector<const Palette*>> chunkPalettes;
    std::vector<std::uint32_t> drawnBefore;
    /// Per instance of the batch: its rectangle within the image (empty where it draws nothing),
    /// its palette's base and its key in the draw order (farOrderKey).
    std::vector<glm::ivec4> rects;
    std::vector<std::uint32_t> paletteOf;
    std::vector<std::uint64_t> keys;
    /// The drawn instances in draw order: their keys and instance indices, sorted; and their
    /// rectangles in that order.
    std::vector<KeyIndex> order;
    KeyIndexScratch orderScratch;
    std::vector<glm::ivec4> sortedRects;
    /// What the order and tile lists above were made from: per instance its entity (kNoEntity
    /// where a copy), the sprites of store `store` as of update `asOf`, the image size.
    struct OrderSource {
        std::uint64_t store = 0, asOf = 0;
        int width = 0, height = 0;
        std::vector<std::uint32_t> entities;
    } orderSource;

    Impl(GpuFrames& f, FarTiles t)
        : frames(f), device(f.device()), tiles(t != FarTiles::Auto ? t : FarTiles::Sprites),
          side(int(tiles == FarTiles::Fine ? far_gpu::FAR_TILE_FINE : far_gpu::FAR_TILE_COARSE)),
          residency(f.device()) {
        if (!FarPass::supported(device))
            throw VulkanError("far pass: " + device.name() +
                              " lacks shaderFloat64, which the far pass needs (--far-backend cpu)");
        try {
            create();
        } catch (...) {
            destroy();
            throw;
        }
    }
    ~Impl() { destroy(); }

    void create();
    void destroy() noexcept;
    void ensure(VulkanBuffer& b, VkDeviceSize bytes);
    void ensureWinners(Slot& slot, VkDeviceSize bytes);
    /// The frame's draw order, palettes, tiles and tile lists (none when cut by sprite), from
    /// `batch` (last frame's order and lists where `history` says they stand). Returns the tiles
    /// to dispatch.
    std::uint32_t prepare(const FarBatch& batch, int width, int height,
                          const SpriteHistory* history, FarPassStats& stats);
    /// Every tile's list of the drawn instances over it, in draw order (`order`).
    void binTiles(int width, int height);
    /// Dispatches of the tile pass that walk the longest list (FAR_LIST_STEP_*).
    std::uint32_t listParts() const;
    /// The pass cut by sprite: the rows of the image its rectangles cover (from y0, whole rows of
    /// the resolve's workgroups, within the image) and the columns from x0.
    struct SplatShape {
        std::uint32_t x0 = 0, y0 = 0, columns = 0, rows = 0;
    };
    /// The pass cut by sprite: its shape, and in `list` the chunks of the drawn rectangles past
    /// each one's first (FAR_SPLAT_CHUNK), as the shader reads them: instance, chunk. One walk
    /// over the drawn instances for both (a rectangle read is a jump through `order`).
    SplatShape planSplat(int width, int height);
    /// The drawn instances' records, in draw order, into the slot's buffer (offsets: each
    /// snapshot's word offset on the device), but for those the buffer already holds.
    void writeInstances(GpuFrame& frame, Slot& slot, const FarBatch& batch,
                        const std::vector<std::uint32_t>& offsets, const SpriteHistory* history,
                        FarPassStats& stats);
    void writeDescriptors(GpuFrame& frame, Slot& slot);
};

void FarPass::Impl::create() {
    VkDevice dev = device.device();
    using namespace far_gpu;
    const VkDescriptorType sb = VK_DESCRIPTOR_TYPE_STORAGE_BUFFER;
    const VkShaderStageFlags c = VK_SHADER_STAGE_COMPUTE_BIT;
    const VkDescriptorSetLayoutBinding bindings[] = {
        {FAR_BINDING_INSTANCES, sb, 1, c, nullptr}, {FAR_BINDING_SNAPSHOTS, sb, 1, c, nullptr},
        {FAR_BINDING_PALETTES, sb, 1, c, nullptr},  {FAR_BINDING_TILES, sb, 1, c, nullptr},
        {FAR_BINDING_TILE_LIST, sb, 1, c, nullptr}, {FAR_BINDING_PLANES, sb, 1, c, nullptr},
        {FAR_BINDING_WINNERS, sb, 1, c, nullptr},
    };
    createPassLayouts(dev, bindings, sizeof(FarPush), setLayout, pipelineLayout);

    const std::uint32_t n = std::uint32_t(frames.slots());
    const VkDescriptorPoolSize sizes[] = {{sb, std::uint32_t(std::size(bindings)) * n}};
    VkDescriptorPoolCreateInfo dpi{VK_STRUCTURE_TYPE_DESCRIPTOR_POOL_CREATE_INFO};
    dpi.maxSets = n;
    dpi.poolSizeCount = 1;
    dpi.pPoolSizes = sizes;
    VK_CHECK(vkCreateDescriptorPool(dev, &dpi, nullptr, &descriptorPool));
    slots.resize(n);
    for (Slot& s : slots) {
        VkDescriptorSetAllocateInfo dsa{VK_STRUCTURE_TYPE_DESCRIPTOR_SET_ALLOCATE_INFO};
        dsa.descriptorPool = descriptorPool;
        dsa.descriptorSetCount = 1;
        dsa.pSetLayouts = &setLayout;
        VK_CHECK(vkAllocateDescriptorSets(dev, &dsa, &s.set));
        for (VulkanBuffer* b : {&s.instances, &s.palettes, &s.tiles, &s.tileList}) ensure(*b, 4096);
        ensureWinners(s, 4096);
    }

    if (tiles == FarTiles::Sprites) {
        pipeline = createComputePipeline(dev, pipelineLayout, far_splat_comp);
        resolvePipeline = createComputePipeline(dev, pipelineLayout, far_resolve_comp);
    } else {
        pipeline = createComputePipeline(dev, pipelineLayout,
                                         tiles == FarTiles::Coarse
                                             ? std::span<const std::uint32_t>(far_blit_coarse_comp)
                                             : std::span<const std::uint32_t>(far_blit_fine_comp));
    }
}

void FarPass::Impl::destroy() noexcept {
    VkDevice dev = device.device();
    if (!dev) return;
    frames.waitAll();
    slots.clear();
    if (pipeline) vkDestroyPipeline(dev, pipeline, nullptr);
    if (resolvePipeline) vkDestroyPipeline(dev, resolvePipeline, nullptr);
    if (descriptorPool) vkDestroyDescriptorPool(dev, descriptorPool, nullptr); // frees the sets
    if (pipelineLayout) vkDestroyPipelineLayout(dev, pipelineLayout, nullptr);
    if (setLayout) vkDestroyDescriptorSetLayout(dev, setLayout, nullptr);
    pipeline = VK_NULL_HANDLE;
    resolvePipeline = VK_NULL_HANDLE;
    descriptorPool = VK_NULL_HANDLE;
    pipelineLayout = VK_NULL_HANDLE;
    setLayout = VK_NULL_HANDLE;
}

void FarPass::Impl::ensure(VulkanBuffer& b, VkDeviceSize bytes) {
    if (b && b.size() >= bytes) return;
    VkDeviceSize size = b ? b.size() : 4096;
    while (size < bytes) size *= 2;
    b = VulkanBuffer(device, size, VK_BUFFER_USAGE_STORAGE_BUFFER_BIT, BufferClass::ShaderRead);
}

void FarPass::Impl::ensureWinners(Slot& slot, VkDeviceSize bytes) {
    if (slot.winners && slot.winners.size() >= bytes) return;
    slot.winners = VulkanBuffer(
        device, bytes, VK_BUFFER_USAGE_STORAGE_BUFFER_BIT | VK_BUFFER_USAGE_TRANSFER_DST_BIT,
        BufferClass::DeviceOnly);
}

std::uint32_t FarPass::Impl::prepare(const FarBatch& batch, int width, int height,
                                     const SpriteHistory* history, FarPassStats& stats) {
    paletteBase.clear();
    palettes.clear();
    const std::size_t n = batch.instances.size();
    constexpr std::uint32_t kNoEntity = KeptRecords::kNoEntity;
    // Last frame's order and tile lists stand where the same store's sprites of the same
    // entities, in the same sequence, drew this frame's instances, none of them moved on screen
    // since (its depth and rectangle: SpriteHistory::spritePosedAt), and the image has its size:
    // a still camera's frame, animation steps included (100,000 far tanks: the keys, the sort
    // and the lists cost ~8 ms of a 2-core host's recording).
    OrderSource& src = orderSource;
    bool same = history && history->store != 0 && src.store == history->store &&
                src.width == width && src.height == height && src.entities.size() == n;
    if (same)
        same = tbb::parallel_reduce(
            tbb::blocked_range<std::size_t>(0, n, 1024), true,
            [&](const auto& range, bool ok) {
                for (std::size_t i = range.begin(); ok && i != range.end(); ++i) {
                    const std::uint32_t e =
                        SpriteHistory::entityIn(history, batch.instances[i].sprite);
                    ok = e != kNoEntity && e == src.entities[i] &&
                         history->spritePosedAt(e) <= src.asOf;
                }
                return ok;
            },
            [](bool a, bool b) { return a && b; });
    stats.orderKept = same;
    src.store = 0; // until the order below is as `src` says
    const auto drawn = [&](std::size_t i) {
        const glm::ivec4 r = rects[i];
        return r.z > r.x && r.w > r.y;
    };
    bool idsAscend = false;
    if (!same) {
        // Each instance's rectangle and order key, read in parallel (a sprite's record is a cache
        // miss apiece: at 100,000 tanks one core walking ten thousand far sprites cost
        // milliseconds of recording).
        rects.resize(n);
        keys.resize(n);
        src.entities.resize(n);
        // Also whether the instances' ids ascend (they come in entity order): then the sort
        // spares the id's digits (sortKeyIndexPairs's tieBits), the order's pairs being a
        // subsequence of the instances.
        const auto readRange = [&](const tbb::blocked_range<std::size_t>& range,
                                   AscendingIds seen) {
            for (std::size_t i = range.begin(); i != range.end(); ++i) {
                const SpriteSetup& s = *batch.instances[i].sprite;
                // The store's own sprite: its visibility, depth and id from the history's
                // per-entity arrays (the sprite's first line is not read); a copy from itself.
                const SpriteHistory::OrderInputs in = SpriteHistory::orderInputs(history, s);
                // The far blit's rectangle: the sprite's screen rectangle within the image.
                rects[i] = in.visible ? glm::clamp(s.screenRect, glm::ivec4(0),
                                                   glm::ivec4(width, height, width, height))
                                      : glm::ivec4(0);
                keys[i] = farOrderKey(in.depth, in.id);
                seen.add(in.id);
                src.entities[i] = in.entity;
            }
            return seen;
        };
        idsAscend = tbb::parallel_reduce(tbb::blocked_range<std::size_t>(0, n, 64), AscendingIds{},
                                         readRange, AscendingIds::join)
                        .ascending;
    }
    // The drawn instances' palettes, each placed where the first drawn instance showing it puts
    // it, and (unless kept) their (key, index) pairs in instance order: each chunk of instances
    // lists its palettes and counts its drawn instances on every core, the lists are merged in
    // chunk order, then each chunk writes from its offsets. Neighbours mostly share their model's
    // palette: the last one found is tried first (one core walking 76,000 far tanks' palettes
    // and pairs cost ~1 ms of a frame; on 16 cores it would be most of the far pass's host side).
    constexpr std::size_t kChunk = 4096;
    const std::size_t chunks = (n + kChunk - 1) / kChunk;
    const auto chunkEnd = [&](std::size_t c) { return std::min(n, (c + 1) * kChunk); };
    chunkPalettes.resize(std::max(chunkPalettes.size(), chunks));
    drawnBefore.assign(chunks + 1, 0);
    tbb::parallel_for(std::size_t(0), chunks, [&](std::size_t c) {
        std::vector<const Palette*>& mine = chunkPalettes[c];
        mine.clear();
        // A few palettes a chunk are compared one by one; a scene of many models interleaved
        // gets a set, so a chunk never costs its instances times its palettes.
        constexpr std::size_t kCompared = 16;
        std::unordered_set<const Palette*> seen;
        const auto isNew = [&](const Palette* p) {
            if (mine.size() <= kCompared)
                return std::find(mine.begin(), mine.end(), p) == mine.end();
            if (seen.empty()) seen.insert(mine.begin(), mine.end());
            return seen.insert(p).second;
        };
        const Palette* last = nullptr;
        std::uint32_t count = 0;
        for (std::size_t i = c * kChunk; i != chunkEnd(c); ++i) {
            if (!drawn(i)) continue;
            ++count;
            const Palette* p = batch.instances[i].palette;
            if (p == last) continue;
            last = p;
            if (isNew(p)) mine.push_back(p);
        }
        drawnBefore[c + 1] = count;
    });
    for (std::size_t c = 0; c < chunks; ++c) {
        drawnBefore[c + 1] += drawnBefore[c];
        for (const Palette* p : chunkPalettes[c])
            if (paletteBase.try_emplace(p, std::uint32_t(palettes.size())).second)
                for (const Rgba8 colour : p->colors) palettes.push_back(std::uint32_t(colour));
    }
    paletteOf.resize(n);
    if (!same) order.resize(drawnBefore[chunks]);
    tbb::parallel_for(std::size_t(0), chunks, [&](std::size_t c) {
        const Palette* last = nullptr;
        std::uint32_t base = 0;
        std::size_t next = drawnBefore[c];
        for (std::size_t i = c * kChunk; i != chunkEnd(c); ++i) {
            if (!drawn(i)) {
                paletteOf[i] = 0;
                continue;
            }
            const Palette* p = batch.instances[i].palette;
            if (p != last) last = p, base = paletteBase.find(p)->second;
            paletteOf[i] = base;
            if (!same) order[next++] = {keys[i], std::uint32_t(i)};
        }
    });
    if (!same) {
        // The drawn instances take their places in the rule's order, nearest first (far_shared.h:
        // the shader stops passing a tile's sprites over a pixel once the pixel would refuse the
        // next one, which is then true of every later one). The (key, index) pairs are distinct,
        // so the order has one answer, whichever sort finds it.
        sortKeyIndexPairs(order, orderScratch, idsAscend ? 32 : 0);
        if (tiles == FarTiles::Sprites) {
            tileRecords.clear(); // no tiles: the chunks' list is planSplat's, every frame
        } else {
            binTiles(width, height);
        }
    }
    if (history && history->store != 0) {
        src.store = history->store;
        src.asOf = history->now;
        src.width = width;
        src.height = height;
    }
    return std::uint32_t(tileRecords.size());
}

void FarPass::Impl::binTiles(int width, int height) {
    const int block = side;
    const int tilesX = (width + block - 1) / block, tilesY = (height + block - 1) / block;
    const auto tileSpan = [&](const glm::ivec4& r) {
        return glm::ivec4(r.x / block, r.y / block, (r.z - 1) / block, (r.w - 1) / block);
    };
    // The rectangles in draw order, gathered on every core: the binning below reads them in
    // sequence (through `order` each was a jump: ~3 ms at 88,000 on one core).
    const std::size_t count = order.size();
    sortedRects.resize(count);
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, count, 1024), [&](const auto& range) {
        for (std::size_t k = range.begin(); k != range.end(); ++k)
            sortedRects[k] = rects[order[k].second];
    });
    // Each tile's sprites in draw order (nearest first), binned on every core: the drawn
    // instances in runs, each run counting its entries per tile, then writing them from the
    // offsets the runs before it leave, so every tile's list keeps the draw order. As many
    // runs as keep the per-run counters within a few times the entries (one run, serial as
    // before, for an image of many tiles and few sprites).
    const std::size_t tileCount = std::size_t(tilesX) * std::size_t(tilesY);
    const std::size_t runs =
        std::clamp<std::size_t>(count / std::max<std::size_t>(tileCount, 4096), 1, 64);
    const std::size_t runLength = (count + runs - 1) / runs;
    runOffsets.assign(runs * tileCount, 0);
    const auto eachTileOf = [&](std::size_t k, auto&& visit) {
        const glm::ivec4 t = tileSpan(sortedRects[k]);
        for (int ty = t.y; ty <= t.w; ++ty)
            for (int tx = t.x; tx <= t.z; ++tx)
                visit(std::size_t(ty) * std::size_t(tilesX) + std::size_t(tx));
    };
    tbb::parallel_for(std::size_t(0), runs, [&](std::size_t r) {
        std::uint32_t* counts = runOffsets.data() + r * tileCount;
        for (std::size_t k = r * runLength; k < std::min(count, (r + 1) * runLength); ++k)
            eachTileOf(k, [&](std::size_t tile) { ++counts[tile]; });
    });
    // Tiles with far sprites; each run's first entry in each tile.
    tileRecords.clear();
    std::uint32_t total = 0;
    for (std::size_t tile = 0; tile < tileCount; ++tile) {
        const std::uint32_t first = total;
        for (std::size_t r = 0; r < runs; ++r) {
            std::uint32_t& c = runOffsets[r * tileCount + tile];
            const std::uint32_t entries = c;
            c = total;
            total += entries;
        }
        if (total == first) continue;
        const std::uint32_t tx = std::uint32_t(tile % std::size_t(tilesX)),
                            ty = std::uint32_t(tile / std::size_t(tilesX));
        const auto px = std::uint32_t(block);
        tileRecords.push_back({tx * px | (ty * px) << 16, first, total - first, 0});
    }
    list.assign(total, 0);
    tbb::parallel_for(std::size_t(0), runs, [&](std::size_t r) {
        std::uint32_t* next = runOffsets.data() + r * tileCount;
        for (std::size_t k = r * runLength; k < std::min(count, (r + 1) * runLength); ++k)
            eachTileOf(k, [&](std::size_t tile) { list[next[tile]++] = std::uint32_t(k); });
    });
}

std::uint32_t FarPass::Impl::listParts() const {
    std::uint32_t longest = 0;
    for (const far_gpu::FarTile& t : tileRecords) longest = std::max(longest, t.count);
    const std::uint32_t step =
        tiles == FarTiles::Fine ? far_gpu::FAR_LIST_STEP_FINE : far_gpu::FAR_LIST_STEP_COARSE;
    return std::max(1u, (longest + step - 1) / step);
}

FarPass::Impl::SplatShape FarPass::Impl::planSplat(int width, int height) {
    glm::ivec4 bounds(width, height, 0, 0);
    // Most far rectangles are one chunk: under the 1 vpx budget 48 of the street's ~390 cover more
    // than two, ~620,000 pixels between them.
    list.clear();
    for (std::size_t k = 0; k < order.size(); ++k) {
        const glm::ivec4 r = rects[order[k].second];
        bounds = glm::ivec4(glm::min(glm::ivec2(bounds), glm::ivec2(r)),
                            glm::max(glm::ivec2(bounds.z, bounds.w), glm::ivec2(r.z, r.w)));
        const std::uint64_t pixels = std::uint64_t(r.z - r.x) * std::uint64_t(r.w - r.y);
        for (std::uint64_t c = 1; c * far_gpu::FAR_SPLAT_CHUNK < pixels; ++c) {
            list.push_back(std::uint32_t(k));
            list.push_back(std::uint32_t(c));
        }
    }
    SplatShape shape;
    // Whole rows of the resolve's 8 x 8 workgroups from the rectangles' first row: every word
    // the resolve reads is filled this frame.
    shape.x0 = std::uint32_t(std::max(bounds.x, 0));
    shape.y0 = std::uint32_t(std::max(bounds.y, 0));
    shape.columns = std::uint32_t(std::max(bounds.z - bounds.x, 0));
    shape.rows = std::min(std::uint32_t(height) - std::min(shape.y0, std::uint32_t(height)),
                          (std::uint32_t(std::max(bounds.w - bounds.y, 0)) + 7u) / 8u * 8u);
    return shape;
}

void FarPass::Impl::writeInstances(GpuFrame& frame, Slot& slot, const FarBatch& batch,
                                   const std::vector<std::uint32_t>& offsets,
                                   const SpriteHistory* history, FarPassStats& stats) {
    const std::size_t drawn = order.size();
    const VkDeviceSize bytes = VkDeviceSize(drawn) * sizeof(far_gpu::FarInstanceGpu);
    ensure(slot.instances, std::max<VkDeviceSize>(bytes, 4));
    if (!drawn) return;
    // What the slot's buffer holds that is still current: a record whose place holds the same
    // instance (entity, snapshot and its device place, palette place) of a sprite that has not
    // changed since, in a buffer the host writes in place (a staged buffer is copied whole from
    // the staging ring). A still camera's frame then writes the records that changed, where it
    // wrote every one (100,000 far tanks: 32 MB, 10-17 ms of a 2-core host).
    KeptRecords& kept = slot.kept;
    const bool direct = slot.instances.placement().hostWrite == HostWrite::Direct;
    const int width = frame.width(), height = frame.height();
    // What this frame writes can be kept by a later frame of the same store only in place.
    const bool remember = history && history->store != 0 && direct;
    const bool keep = remember && kept.store == history->store &&
                      kept.buffer == slot.instances.handle() && kept.width == width &&
                      kept.height == height;
    kept.store = 0; // until every place below is as `kept` says (an exception leaves it so)
    kept.places.resize(remember ? drawn : 0);
    // Straight into the buffer (mapped, or the staging ring's space for it), each record composed
    // first and stored once, in order: the destination may be write-combined device memory, and
    // a copy through a host array wrote each record twice (368 bytes a sprite then, 32 MB at
    // 88,000 far tanks; 192 since a record holds only what the pass reads of its sprite).
    auto* out = static_cast<far_gpu::FarInstanceGpu*>(frame.hostWrite(slot.instances, 0, bytes));
    stats.recordsKept = tbb::parallel_reduce(
        tbb::blocked_range<std::size_t>(0, drawn, 64), std::uint64_t(0),
        [&](const auto& range, std::uint64_t keptHere) {
            for (std::size_t k = range.begin(); k != range.end(); ++k) {
                // In draw order each instance, and its sprite's record, is a jump through memory
                // (in instance order they were read in sequence): their lines are asked for ahead,
                // the instance's first, then, once it is at hand, its sprite's (100,000 far tanks
                // moving: 7-9 ms of this 2-core host's recording without).
                if (k + 2 * kReadAhead < drawn)
                    __builtin_prefetch(&batch.instances[order[k + 2 * kReadAhead].second]);
                if (k + kReadAhead < drawn) {
                    const auto* ahead = reinterpret_cast<const char*>(
                        &batch.instances[order[k + kReadAhead].second].sprite->gpu);
                    for (std::size_t b = 0; b < sizeof(kernel::SpriteGpu); b += 64)
                        __builtin_prefetch(ahead + b);
                }
                const std::uint32_t i = order[k].second;
                const FarInstance& f = batch.instances[i];
                const FarSnapshotCells& snap = batch.snapshots.at(f.snapshot);
                const auto bits = [](double v) { return std::bit_cast<std::uint64_t>(v); };
                const KeptRecords::Place place{
                    SpriteHistory::entityIn(history, f.sprite),
                    {offsets[f.snapshot], std::uint32_t(snap.width()), std::uint32_t(snap.height()),
                     std::uint32_t(snap.cellRange.x)},
                    snap.cellRange.z,
                    std::int32_t(paletteOf[i]),
                    {bits(f.u0), bits(f.ui), bits(f.uj), bits(f.v0), bits(f.vi), bits(f.vj)}};
                if (keep && place.entity != KeptRecords::kNoEntity && kept.places[k] == place &&
                    history->spriteChangedAt(place.entity) <= kept.asOf) {
                    ++keptHere;
                    continue;
                }
                far_gpu::FarInstanceGpu g{};
                g.sprite = far_gpu::farSpriteOf(f.sprite->gpu);
                g.u0 = f.u0, g.ui = f.ui, g.uj = f.uj, g.v0 = f.v0, g.vi = f.vi, g.vj = f.vj;
                g.rect = rects[i];
                g.snap = place.snap;
                g.extra = {place.firstCellJ, place.palette, std::bit_cast<int>(f.sprite->gpu.depth),
                           int(f.sprite->entityId)};
                out[k] = g;
                if (remember) kept.places[k] = place;
            }
            return keptHere;
        },
        std::plus<>());
    if (remember) {
        kept.store = history->store;
        kept.asOf = history->now;
        kept.buffer = slot.instances.handle();
        kept.width = width;
        kept.height = height;
    }
}

void FarPass::Impl::writeDescriptors(GpuFrame& frame, Slot& slot) {
    using namespace far_gpu;
    const std::pair<std::uint32_t, VkBuffer> buffers[] = {
        {FAR_BINDING_INSTANCES, slot.instances.handle()},
        {FAR_BINDING_SNAPSHOTS, residency.buffer()},
        {FAR_BINDING_PALETTES, slot.palettes.handle()},
        {FAR_BINDING_TILES, slot.tiles.handle()},
        {FAR_BINDING_TILE_LIST, slot.tileList.handle()},
        {FAR_BINDING_PLANES, frame.planes()},
        {FAR_BINDING_WINNERS, slot.winners.handle()},
    };
    constexpr std::size_t kBuffers = std::size(buffers);
    VkDescriptorBufferInfo infos[kBuffers];
    VkWriteDescriptorSet w[kBuffers]{};
    for (std::size_t i = 0; i < kBuffers; ++i) {
        infos[i] = {buffers[i].second, 0, VK_WHOLE_SIZE};
        w[i].sType = VK_STRUCTURE_TYPE_WRITE_DESCRIPTOR_SET;
        w[i].dstSet = slot.set;
        w[i].dstBinding = buffers[i].first;
        w[i].descriptorCount = 1;
        w[i].descriptorType = VK_DESCRIPTOR_TYPE_STORAGE_BUFFER;
        w[i].pBufferInfo = &infos[i];
    }
    vkUpdateDescriptorSets(device.device(), std::uint32_t(kBuffers), w, 0, nullptr);
}

FarPass::FarPass(GpuFrames& frames, FarTiles tiles)
    : impl_(std::make_unique<Impl>(frames, tiles)) {}
FarPass::~FarPass() = default;

FarTiles FarPass::tiles() const {
    return impl_->tiles;
}

std::uint64_t FarPass::residentBytes() const {
    return impl_->residency.residentBytes();
}
std::size_t FarPass::residentSnapshots() const {
    return impl_->residency.residentSnapshots();
}

void FarPass::record(GpuFrame& frame, const FarBatch& batch, FarPassStats& stats,
                     const SpriteHistory* history) {
    Impl& m = *impl_;
    if (3 * frame.planeBytes() > m.device.properties().limits.maxStorageBufferRange)
        throw VulkanError("far pass: the image is larger than the device's storage buffer range");
    Impl::Slot& slot = m.slots.at(std::size_t(frame.slot()));
    VkCommandBuffer cb = frame.commandBuffer();
    FarResidencyStats rs;
    const std::vector<std::uint32_t> offsets = m.residency.update(batch, &rs);
    stats.snapshotsUploaded = rs.snapshotsUploaded;
    stats.bytesUploaded = rs.bytesUploaded;
    const std::uint32_t tileCount = m.prepare(batch, frame.width(), frame.height(), history, stats);
    stats.sprites = m.order.size();
    stats.tiles = tileCount;

    const bool bySprite = m.tiles == FarTiles::Sprites;
    const std::uint32_t width = std::uint32_t(frame.width()),
                        height = std::uint32_t(frame.height());
    const Impl::SplatShape shape =
        bySprite ? m.planSplat(int(width), int(height)) : Impl::SplatShape{};

    frame.timer().begin(cb, "far_upload");
    // The snapshots' uploads timed apart (host and device): a snapshot is uploaded once, when
    // first drawn, and the cost bound's blit rate leaves them out (CostModel::observe).
    frame.timer().begin(cb, "far_snapshots");
    const auto tSnapshots = std::chrono::steady_clock::now();
    m.residency.recordUploads(frame);
    stats.snapshotUploadMs = msSince(tSnapshots);
    frame.timer().end(cb);
    const auto upload = [&](VulkanBuffer& b, const auto& v) {
        const VkDeviceSize bytes = v.size() * sizeof(v[0]);
        m.ensure(b, std::max<VkDeviceSize>(bytes, 4));
        frame.hostCopy(b, v.data(), bytes);
    };
    m.writeInstances(frame, slot, batch, offsets, history, stats);
    upload(slot.palettes, m.palettes);
    upload(slot.tiles, m.tileRecords);
    upload(slot.tileList, m.list);
    if (m.tiles == FarTiles::Sprites)
        m.ensureWinners(slot, VkDeviceSize(frame.width()) * VkDeviceSize(frame.height()) *
                                  sizeof(std::uint32_t));
    m.writeDescriptors(frame, slot);
    frame.ring().recordBarrier(cb, VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT, VK_ACCESS_SHADER_READ_BIT);
    frame.timer().end(cb);
    // Workgroups: one per tile, or one per chunk of each drawn instance's rectangle.
    const std::uint32_t instances = std::uint32_t(m.order.size());
    const std::uint32_t groups =
        bySprite ? instances + std::uint32_t(m.list.size() / 2) : tileCount;
    if (bySprite) stats.splatGroups = groups;
    if (!groups) return;

    frame.timer().begin(cb, "far_blit");
    if (bySprite) {
        // Every pixel the resolve reads starts with no winner: the rows the rectangles cover, in
        // whole rows of its workgroups (after the last frame's resolve read this slot's).
        vkCmdFillBuffer(cb, slot.winners.handle(), VkDeviceSize(shape.y0) * width * 4u,
                        VkDeviceSize(shape.rows) * width * 4u, far_gpu::FAR_NO_WINNER);
        bufferBarrier(cb, slot.winners.handle(), VK_PIPELINE_STAGE_TRANSFER_BIT,
                      VK_ACCESS_TRANSFER_WRITE_BIT, VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT,
                      VK_ACCESS_SHADER_READ_BIT | VK_ACCESS_SHADER_WRITE_BIT);
    }
    // After the near tier's writes to the planes (copies and compute).
    bufferBarrier(cb, frame.planes(),
                  VK_PIPELINE_STAGE_TRANSFER_BIT | VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT,
                  VK_ACCESS_TRANSFER_WRITE_BIT | VK_ACCESS_SHADER_WRITE_BIT,
                  VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT,
                  VK_ACCESS_SHADER_READ_BIT | VK_ACCESS_SHADER_WRITE_BIT);
    const std::uint32_t maxX = m.device.properties().limits.maxComputeWorkGroupCount[0];
    const std::uint32_t groupsX = std::min(groups, maxX);
    vkCmdBindPipeline(cb, VK_PIPELINE_BIND_POINT_COMPUTE, m.pipeline);
    vkCmdBindDescriptorSets(cb, VK_PIPELINE_BIND_POINT_COMPUTE, m.pipelineLayout, 0, 1, &slot.set,
                            0, nullptr);
    // No invocation loops past lavapipe's limit (far_shared.h): a tile's list is walked in parts,
    // a dispatch each (a chunk of a rectangle is 16 steps).
    const std::uint32_t parts = bySprite ? 1u : m.listParts();
    for (std::uint32_t part = 0; part < parts; ++part) {
        if (part > 0) // the last part's writes to the planes before this part reads them
            bufferBarrier(cb, frame.planes(), VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT,
                          VK_ACCESS_SHADER_WRITE_BIT, VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT,
                          VK_ACCESS_SHADER_READ_BIT | VK_ACCESS_SHADER_WRITE_BIT);
        const far_gpu::FarPush push{groups, width, height, bySprite ? instances : part, 0u};
        vkCmdPushConstants(cb, m.pipelineLayout, VK_SHADER_STAGE_COMPUTE_BIT, 0, sizeof push,
                           &push);
        vkCmdDispatch(cb, groupsX, (groups + groupsX - 1) / groupsX, 1u);
    }
    if (bySprite) {
        // The winners complete, and the planes read by the splat, before the resolve writes them.
        const VkMemoryBarrier mb{VK_STRUCTURE_TYPE_MEMORY_BARRIER, nullptr,
                                 VK_ACCESS_SHADER_READ_BIT | VK_ACCESS_SHADER_WRITE_BIT,
                                 VK_ACCESS_SHADER_READ_BIT | VK_ACCESS_SHADER_WRITE_BIT};
        vkCmdPipelineBarrier(cb, VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT,
                             VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT, 0, 1, &mb, 0, nullptr, 0,
                             nullptr);
        // Over the rectangles' bounds only (the hybrid's far tanks: a band of the horizon).
        vkCmdBindPipeline(cb, VK_PIPELINE_BIND_POINT_COMPUTE, m.resolvePipeline);
        const far_gpu::FarPush push{groups, width, height, 0u, shape.x0 | shape.y0 << 16};
        vkCmdPushConstants(cb, m.pipelineLayout, VK_SHADER_STAGE_COMPUTE_BIT, 0, sizeof push,
                           &push);
        vkCmdDispatch(cb, (shape.columns + 7) / 8, (shape.rows + 7) / 8, 1);
    }
    frame.timer().end(cb);
    bufferBarrier(
        cb, frame.planes(), VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT, VK_ACCESS_SHADER_WRITE_BIT,
        VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT | VK_PIPELINE_STAGE_TRANSFER_BIT,
        VK_ACCESS_SHADER_READ_BIT | VK_ACCESS_SHADER_WRITE_BIT | VK_ACCESS_TRANSFER_READ_BIT);
}

} // namespace voxtier
