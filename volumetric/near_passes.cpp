// NearPasses recording a frame: the host writes what the passes read, then records them (the
// Vulkan objects they use are created in near_passes_create.cpp).
#include "volumetric/near_passes.hpp"

#include "core/occlusion.hpp"
#include "core/running_totals.hpp"
#include "core/stopwatch.hpp"
#include "volumetric/detail/near_passes_impl.hpp"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/parallel_reduce.h>

#include <algorithm>
#include <array>
#include <atomic>
#include <chrono>
#include <cstdint>
#include <map>
#include <utility>

namespace voxtier {

namespace {

// The plan's marker and the shaders' marker are one value: near_shared.h is not installed with
// the public core/near_rate.hpp, so the two spellings are tied here instead of by an include.
static_assert(kNoCells == near_gpu::NEAR_NO_CELLS);
static_assert(kMaxCellSprites == near_gpu::NEAR_MAX_CELL_SPRITES);
static_assert(kMaxHullCorners == int(near_gpu::NEAR_HULL_MAX_VERTICES));

/// Sprites per task of the host's per-sprite loops, at most: enough work that TBB's overhead
/// vanishes, and a few thousand sprites still spread over 16 cores (the auto partitioner splits
/// no finer than it must).
constexpr std::size_t kSpriteGrain = 64;

/// How many sprites ahead the gather of sprite records prefetches: enough for the lines to
/// arrive from memory while the records between are copied.
constexpr std::size_t kGatherAhead = 8;

/// Whether every frame placed in `before` lies where it did (frames placed since may be added):
/// a record written then still names its voxels and occupancy.
bool placedAsBefore(const VoxelResidency::Placements& before,
                    const VoxelResidency::Placements& now) {
    if (before.first != now.first || before.frames.size() != now.frames.size()) return false;
    for (std::size_t f = 0; f < before.frames.size(); ++f)
        if (before.frames[f].present && !(before.frames[f] == now.frames[f])) return false;
    return true;
}

} // namespace

// ---------------------------------------------------------------------------------------------
// The host's part of a frame: what the passes read, written straight where they read it

bool NearPasses::Impl::orderSprites(std::span<const SpriteSetup* const> all, const NearOptions& opt,
                                    const SpriteHistory* history, bool& unchanged) {
    constexpr std::uint32_t kNoEntity = KeptRecords::kNoEntity;
    const auto entityAt = [&](std::size_t k) { return SpriteHistory::entityIn(history, all[k]); };
    // Last frame's order, while the sprites given are the same entities' and none of them was set
    // up anew since (an animation step changes neither depth nor visibility). Else a parallel
    // sort of every sprite's depth, each sprite a cache miss: 5 ms of a still camera's frame at
    // 100,000 tanks on two cores.
    KeptOrder& kept = keptOrder;
    using Same = std::pair<bool, bool>; // the order; the order and the animation frames
    const bool comparable = history && history->store != 0 && opt.earlyDepthTest &&
                            kept.store == history->store && kept.entity.size() == all.size();
    const Same same =
        !comparable ? Same{false, false}
                    : tbb::parallel_reduce(
                          tbb::blocked_range<std::size_t>(0, all.size(), 4096), Same{true, true},
                          [&](const auto& r, Same ok) {
                              for (std::size_t k = r.begin(); ok.first && k != r.end(); ++k) {
                                  const std::uint32_t e = entityAt(k);
                                  ok.first = e != kNoEntity && kept.entity[k] == e &&
                                             history->spritePosedAt(e) <= kept.asOf;
                                  ok.second = ok.second && ok.first &&
                                              history->spriteChangedAt(e) <= kept.asOf;
                              }
                              return Same{ok.first, ok.first && ok.second};
                          },
                          [](Same x, Same y) {
                              return Same{x.first && y.first, x.second && y.second};
                          });
    unchanged = same.second;
    // The drawn sprites in the order, gathered on every core (100,000 sprites: a pass over
    // each array, which one core paid as a loop apiece).
    const auto gather = [&] {
        visible.resize(kept.order.size());
        tbb::parallel_for(tbb::blocked_range<std::size_t>(0, visible.size(), 4096),
                          [&](const auto& r) {
                              for (std::size_t i = r.begin(); i != r.end(); ++i)
                                  visible[i] = all[kept.order[i]];
                          });
    };
    if (same.first) {
        gather();
        kept.asOf = history->now;
        return true;
    }
    // §6: front to back with equal depths in ascending id under the early depth test, which
    // keeps every pixel the same (the depth test alone decides unequal depths, whatever their
    // order); else ascending entity id, so that depth GREATER resolves ties to the lower id.
    drawOrder(all, opt.earlyDepthTest, kept.buffers, kept.order, history);
    if (!opt.earlyDepthTest)
        std::stable_sort(
            kept.order.begin(), kept.order.end(),
            [&](std::uint32_t a, std::uint32_t b) { return all[a]->entityId < all[b]->entityId; });
    gather(); // visible[p] == all[kept.order[p]], which the records' places follow
    kept.store = history && opt.earlyDepthTest ? history->store : 0;
    kept.asOf = history ? history->now : 0;
    kept.entity.resize(all.size());
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, all.size(), 4096), [&](const auto& r) {
        for (std::size_t k = r.begin(); k != r.end(); ++k) kept.entity[k] = entityAt(k);
    });
    return false;
}

void NearPasses::Impl::writeSprites(GpuFrame& frame, Slot& slot,
                                    const std::vector<std::shared_ptr<VoxelModel>>& models,
                                    std::span<const SpriteSetup* const> all, const NearOptions& opt,
                                    NearRate rate, NearStats& stats, const SpriteHistory* history) {
    bool unchanged = false;
    const auto tOrder = std::chrono::steady_clock::now();
    stats.drawOrderKept = orderSprites(all, opt, history, unchanged);
    stats.sprites = visible.size();
    stats.recordOrderMs = msSince(tOrder);
    const auto tResidency = std::chrono::steady_clock::now();

    // The residency walks every sprite for the first showing of each model frame: not where the
    // same sprites show the same frames in the same order as last frame. Else, where the drawn
    // sprites are the given ones in the kept order (under the early depth test), the first
    // showings are found from the given sprites in their own order and their places in the drawn
    // one: a moving camera's frame reads them in sequence instead of a cache miss each (100,000
    // tanks moving, 2-core host: residency 2.4-3.6 -> 1.2-1.9 ms).
    firstShowings.valid = firstShowings.valid && unchanged;
    stats.firstShowingsKept = firstShowings.valid;
    if (!firstShowings.valid && opt.earlyDepthTest) {
        places.assign(all.size(), VoxelResidency::kNotShown);
        const std::vector<std::uint32_t>& drawn = keptOrder.order;
        tbb::parallel_for(tbb::blocked_range<std::size_t>(0, drawn.size(), 4096),
                          [&](const auto& r) {
                              for (std::size_t p = r.begin(); p != r.end(); ++p)
                                  places[drawn[p]] = std::uint32_t(p);
                          });
        firstShowings = {true, VoxelResidency::firstShowingsAt(models, all, places)};
    }
    const ResidencyStats up = residency.update(models, visible, &firstShowings);
    stats.bytesUploaded = up.bytesUploaded;
    stats.uploadRegions = up.regions;
    stats.atlasGrowths = up.atlasGrowths;
    stats.uploadMs = up.milliseconds;

    const std::size_t n = visible.size();
    const bool byGiven = opt.records == NearRecords::Given;
    // Record r's sprite: the r-th given (NearRecords::Given) or the r-th drawn.
    const std::size_t records = byGiven ? all.size() : n;
    const VkDeviceSize bytes = VkDeviceSize(records) * sizeof(kernel::SpriteGpu);
    ensure(slot.sprites, std::max<VkDeviceSize>(bytes, 4));
    ensure(slot.recordOf, std::max<VkDeviceSize>(VkDeviceSize(n) * sizeof(std::uint32_t), 4));
    if (!n) {
        placeDepths = {}, placeRects = {}, placeWishes = {};
        stats.recordResidencyMs = msSince(tResidency);
        return;
    }
    residency.placements(models, placements);
    stats.recordResidencyMs = msSince(tResidency);
    // What the slot's buffer holds that is still current: a record stays where the same entity's
    // sprite sat when the slot was last written and has not changed since, in a buffer the host
    // writes in place (a staged buffer is copied whole from the staging ring), with the frames it
    // placed where they were and the same rate (whichever NearRecords laid it out: `kept.entity`
    // says whose record each index holds). A still camera's frame then writes the sprites that
    // changed, where it wrote and gathered every record (100,000 tanks: 18 MB of 208-byte
    // records, each a cache miss).
    KeptRecords& kept = slot.kept;
    const bool direct = slot.sprites.placement().hostWrite == HostWrite::Direct;
    const bool keep = history && history->store != 0 && direct && kept.store == history->store &&
                      kept.rate == rate && kept.buffer == slot.sprites.handle() &&
                      placedAsBefore(kept.placements, placements);
    kept.store = 0; // until every record below is as `kept` says (an exception leaves it so)
    constexpr std::uint32_t kNoEntity = KeptRecords::kNoEntity;
    kept.entity.resize(records, kNoEntity);
    kept.depths.resize(records);
    kept.rects.resize(records);
    kept.wishes.resize(records);
    auto* gpu = static_cast<kernel::SpriteGpu*>(frame.hostWrite(slot.sprites, 0, bytes));
    using Counts = std::pair<std::uint64_t, std::uint64_t>; // records kept, records patched
    // What each record does: written whole, patched (an animation step since the slot's write)
    // or kept.
    enum class Keeps { Nothing, AllButTheFrame, Everything };
    const auto keeps = [&](std::size_t r, std::uint32_t e) {
        if (!keep || e == kNoEntity || kept.entity[r] != e || history->spritePosedAt(e) > kept.asOf)
            return Keeps::Nothing;
        return history->spriteChangedAt(e) <= kept.asOf ? Keeps::Everything : Keeps::AllButTheFrame;
    };
    const auto spriteOf = [&](std::size_t r) { return byGiven ? all[r] : visible[r]; };
    const Counts counts = tbb::parallel_reduce(
        tbb::blocked_range<std::size_t>(0, records, kSpriteGrain), Counts{0, 0},
        [&](const auto& range, Counts c) {
            for (std::size_t r = range.begin(); r != range.end(); ++r) {
                const SpriteSetup* s = spriteOf(r);
                if (byGiven) {
                    // Not drawn (no place names it): its record is never read.
                    if (!s || !s->visible()) {
                        kept.entity[r] = kNoEntity;
                        continue;
                    }
                } else if (const std::size_t a = r + kGatherAhead; a < n) {
                    // In draw order each record read is a jump through the sprite store: the
                    // lines of a record to be written are asked for a few sprites ahead, while
                    // this one is copied (100,000 tanks on the 2-core host: the loop 10.5-12.7
                    // -> 7.6-9.2 ms, medians).
                    const auto* ahead = reinterpret_cast<const char*>(&visible[a]->gpu);
                    if (keeps(a, SpriteHistory::entityIn(history, visible[a])) == Keeps::Nothing)
                        for (std::size_t b = 0; b < sizeof(kernel::SpriteGpu); b += 64)
                            __builtin_prefetch(ahead + b);
                }
                const std::uint32_t e = SpriteHistory::entityIn(history, s);
                if (const Keeps keeping = keeps(r, e); keeping != Keeps::Nothing) {
                    // The record holds this entity's sprite as it is now, or as it was before an
                    // animation step (restepSprite): then only the fields that follow the frame
                    // are written, the voxels' and occupancy's places and the skip rule (a crowd
                    // steps every sprite at once, a few times a second). The lists' figures
                    // depend on neither, and the slot's arrays keep them.
                    if (keeping == Keeps::Everything) {
                        ++c.first;
                        continue;
                    }
                    const VoxelResidency::Placements::Frame& at =
                        placements.at(std::size_t(s->model), s->frame);
                    gpu[r].atlas = at.atlas;
                    gpu[r].brickBase = at.brickBase;
                    gpu[r].skipEmpty = s->gpu.skipEmpty;
                    ++c.second;
                    continue;
                }
                // The only fields the near tier adds to what core computed: where the voxels and
                // their brick occupancy are. Composed here and stored once: the destination may
                // be write-combined device memory (resizable BAR, written directly), where
                // patching a record after storing it writes its lines twice across the bus.
                kernel::SpriteGpu g = s->gpu;
                const VoxelResidency::Placements::Frame& at =
                    placements.at(std::size_t(s->model), s->frame);
                g.atlas = at.atlas;
                g.brickBase = at.brickBase;
                gpu[r] = g;
                // What the rate plan and the work lists read, kept beside the record (the frames
                // that keep the record keep these).
                kept.depths[r] = g.depth;
                kept.rects[r] = s->screenRect;
                kept.wishes[r] = cellRateWish(*s, rate);
                kept.entity[r] = e;
            }
            return c;
        },
        [](Counts a, const Counts& b) {
            return Counts{a.first + b.first, a.second + b.second};
        });
    stats.recordsKept = counts.first;
    stats.recordsPatched = counts.second;
    kept.store = history && direct ? history->store : 0;
    kept.asOf = history ? history->now : 0;
    kept.rate = rate;
    kept.buffer = slot.sprites.handle();
    kept.placements = placements;
    // Each place's record, and what the ranking, the rate plan and the work lists read of it in
    // the draw order: the slot's arrays themselves where the records lie there, else gathered
    // from them (compact arrays, not the sprites).
    auto* recordOf = static_cast<std::uint32_t*>(
        frame.hostWrite(slot.recordOf, 0, VkDeviceSize(n) * sizeof(std::uint32_t)));
    if (!byGiven) {
        tbb::parallel_for(tbb::blocked_range<std::size_t>(0, n, 4096), [&](const auto& range) {
            for (std::size_t p = range.begin(); p != range.end(); ++p)
                recordOf[p] = std::uint32_t(p);
        });
        placeDepths = kept.depths, placeRects = kept.rects, placeWishes = kept.wishes;
        return;
    }
    const std::vector<std::uint32_t>& order = keptOrder.order; // visible[p] == all[order[p]]
    gatheredDepths.resize(n);
    gatheredRects.resize(n);
    gatheredWishes.resize(n);
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, n, 4096), [&](const auto& range) {
        for (std::size_t p = range.begin(); p != range.end(); ++p) {
            const std::uint32_t r = order[p];
            recordOf[p] = r;
            gatheredDepths[p] = kept.depths[r];
            gatheredRects[p] = kept.rects[r];
            gatheredWishes[p] = kept.wishes[r];
        }
    });
    placeDepths = gatheredDepths, placeRects = gatheredRects, placeWishes = gatheredWishes;
}

void NearPasses::Impl::writeProxies(GpuFrame& frame, Slot& slot, const CameraFrame& cam,
                                    const NearOptions& opt, NearStats& stats) {
    const std::size_t n = visible.size();
    flat.assign(n, 0);
    if (!n) return;
    // One record a sprite, composed by make(i) and stored once (as the sprites are).
    const auto writeEach = [&](VulkanBuffer& buffer, auto make) {
        using Record = decltype(make(std::size_t(0)));
        const VkDeviceSize bytes = VkDeviceSize(n) * sizeof(Record);
        ensure(buffer, bytes);
        auto* out = static_cast<Record*>(frame.hostWrite(buffer, 0, bytes));
        tbb::parallel_for(tbb::blocked_range<std::size_t>(0, n, kSpriteGrain), [&](const auto& r) {
            for (std::size_t i = r.begin(); i != r.end(); ++i) out[i] = make(i);
        });
    };
    if (opt.proxy == NearProxy::Box)
        writeEach(slot.boxes, [&](std::size_t i) {
            const auto corners = proxyBoxClipCorners(cam, *visible[i]);
            near_gpu::NearBox b;
            for (int k = 0; k < 8; ++k) b.corner[k] = glm::vec4(corners[std::size_t(k)]);
            return b;
        });
    if (opt.proxy == NearProxy::Quad) {
        // The quad's four corners, as set-up computed them, in the hull buffer (strip order).
        writeEach(slot.hulls, [&](std::size_t i) {
            near_gpu::NearHull h{};
            h.count = 4;
            for (std::size_t k = 0; k < 4; ++k) h.corner[k] = visible[i]->quad[k];
            return h;
        });
        return;
    }
    if (opt.proxy != NearProxy::Hull) return;
    // Hull sprites under the early depth test are rasterised flat at their own depth where that
    // clips nothing the perspective proxy keeps: every corner in front of the eye and within the
    // depth range. Then the corners are divided through on the host (w = 1) and z is the
    // sprite's depth, so every fragment's depth is that float exactly (a triangle of equal z has
    // zero depth slope). The rest (sprites through the near plane) keep the perspective proxy
    // and the shader's depth.
    writeEach(slot.hulls, [&](std::size_t i) {
        std::array<glm::dvec4, kMaxHullCorners> corners;
        const int count = proxyHullClipCorners(cam, *visible[i], corners);
        near_gpu::NearHull h{};
        h.count = std::uint32_t(count);
        bool flatten = opt.earlyDepthTest;
        for (int k = 0; k < count; ++k) {
            const glm::dvec4& c = corners[std::size_t(k)];
            flatten = flatten && c.w > 0.0 && c.z >= 0.0 && c.z <= c.w;
        }
        flat[i] = flatten;
        for (int k = 0; k < count; ++k) {
            const glm::dvec4& c = corners[std::size_t(k)];
            h.corner[k] =
                flatten ? glm::vec4(float(c.x / c.w), float(c.y / c.w), visible[i]->gpu.depth, 1.0f)
                        : glm::vec4(c);
        }
        return h;
    });
    stats.earlyDepthSprites = std::uint64_t(std::count(flat.begin(), flat.end(), std::uint8_t(1)));
}

NearPasses::Impl::CellWork NearPasses::Impl::writeCells(GpuFrame& frame, Slot& slot,
                                                        const CellRatePlan& plan,
                                                        std::uint64_t budgetBytes, bool tracePixels,
                                                        NearStats& stats) {
    const int width = frame.width(), height = frame.height();
    const auto upload = [&](VulkanBuffer& b, const auto& v) {
        const auto t = std::chrono::steady_clock::now();
        const VkDeviceSize bytes = v.size() * sizeof(v[0]);
        ensure(b, std::max<VkDeviceSize>(bytes, 4));
        frame.hostCopy(b, v.data(), bytes);
        stats.recordListsUploadMs += msSince(t);
    };
    upload(slot.cellBases, plan.cellBase);
    // The store is kept for the next frames and grows by doubling, never past the budget (the
    // plan never needs more than the budget).
    const VkDeviceSize need = plan.cells * kCellStoreBytesPerCell;
    if (cells.size() < need) {
        // The store is shared by the frames in flight: the old one lives until this frame is
        // done, which the queue finishes after every earlier frame.
        const VkDeviceSize size =
            std::max(need, std::min<VkDeviceSize>(2 * cells.size(), budgetBytes));
        if (cells) frame.keepUntilDone(std::move(cells));
        cells =
            VulkanBuffer(device, size, VK_BUFFER_USAGE_STORAGE_BUFFER_BIT, BufferClass::DeviceOnly);
    }
    if (!cells) ensure(cells, 4096, BufferClass::DeviceOnly);
    const auto tBuild = std::chrono::steady_clock::now();
    const CellWork work = buildWorkLists(plan, tracePixels, width, height);
    stats.recordListsBuildMs += msSince(tBuild);
    upload(slot.cellTiles, tiles);
    upload(slot.splatBlocks, blocks);
    upload(slot.rankSprites, byDepth);
    return work;
}

void NearPasses::Impl::rankSprites(const CellRatePlan& plan, bool tracePixels) {
    const std::size_t n = visible.size();
    // The ranked sprites: the cell-rate ones, and with tracePixels all. `visible` is in draw
    // order with equal depths in ascending entity id, so a stable sort by depth alone gives
    // Image::writeIfNearer's order: the least rank in a pixel is the sprite the depth test keeps.
    // Under the early depth test `visible` is front to back already, and the sort is skipped.
    const auto isRanked = [&](std::size_t k) {
        return tracePixels || plan.cellBase[k] != kNoCells;
    };
    const auto nearer = [&](std::uint32_t a, std::uint32_t b) {
        return placeDepths[a] > placeDepths[b];
    };
    bool sorted = true;
    if (!runningTotalsInParallel(n)) {
        byDepth.clear();
        for (std::size_t k = 0; k < n; ++k)
            if (isRanked(k)) byDepth.push_back(std::uint32_t(k));
        sorted = std::is_sorted(byDepth.begin(), byDepth.end(), nearer);
    } else {
        // Gathered and checked for depth order per chunk over the cores (on the H200's host the
        // serial gather, check and fill were 0.3 ms of the lists at 84,000 sprites, run 14b).
        const std::size_t chunks = chunkCount(n);
        chunkSums.assign(chunks + 1, 0);
        forEachChunk(n, [&](std::size_t c, std::size_t first, std::size_t end) {
            std::uint64_t count = 0;
            for (std::size_t k = first; k != end; ++k) count += isRanked(k);
            chunkSums[c + 1] = count;
        });
        for (std::size_t c = 0; c < chunks; ++c) chunkSums[c + 1] += chunkSums[c];
        byDepth.resize(std::size_t(chunkSums[chunks]));
        chunkSorted.assign(chunks, 1);
        forEachChunk(n, [&](std::size_t c, std::size_t first, std::size_t end) {
            const std::size_t from = std::size_t(chunkSums[c]);
            std::size_t at = from;
            for (std::size_t k = first; k != end; ++k)
                if (isRanked(k)) {
                    byDepth[at] = std::uint32_t(k);
                    if (at > from && nearer(byDepth[at], byDepth[at - 1])) chunkSorted[c] = 0;
                    ++at;
                }
        });
        // In order where every chunk is and each chunk's first follows the last before it.
        for (std::size_t c = 0; c < chunks && sorted; ++c) {
            const std::size_t at = std::size_t(chunkSums[c]);
            sorted = chunkSorted[c] && (at == 0 || at == std::size_t(chunkSums[c + 1]) ||
                                        !nearer(byDepth[at], byDepth[at - 1]));
        }
    }
    if (!sorted) std::stable_sort(byDepth.begin(), byDepth.end(), nearer);
    // Every sprite ranked (the per-pixel trace's frames): each rank is written below.
    if (byDepth.size() == n)
        ranks.resize(n);
    else
        ranks.assign(n, near_gpu::NEAR_NO_RANK);
    const std::size_t ranked = byDepth.size();
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, ranked, kSpriteGrain), [&](const auto& r) {
        for (std::size_t i = r.begin(); i != r.end(); ++i) ranks[byDepth[i]] = std::uint32_t(i);
    });
}

NearPasses::Impl::CellWork NearPasses::Impl::buildWorkLists(const CellRatePlan& plan,
                                                            bool tracePixels, int width,
                                                            int height) {
    using near_gpu::NEAR_SPLAT_BLOCK;
    const std::size_t n = visible.size();
    rankSprites(plan, tracePixels);
    // Each sprite's cell tiles (cell-rate) and its rectangle's blocks (the splat's, 32 pixels a
    // side, for a cell-rate sprite; the trace's, traceShape.side, for a per-pixel one), in
    // `visible` order, written in parallel
    // at offsets counted first: the trace's blocks go nearest first under the early depth test,
    // so a nearer sprite's words are mostly written before a farther one reads them and the
    // farther one skips the pixels it has lost. The resolve's tiles: every 32x32 tile of the
    // image grid that a ranked rectangle touches, once, so that a frame with a few small
    // cell-rate sprites resolves a few tiles and not the whole image.
    const int tilesX = (width + int(NEAR_SPLAT_BLOCK) - 1) / int(NEAR_SPLAT_BLOCK);
    const int tilesY = (height + int(NEAR_SPLAT_BLOCK) - 1) / int(NEAR_SPLAT_BLOCK);
    touched.assign(std::size_t(tilesX) * std::size_t(tilesY), 0);
    const auto rectOf = [&](std::size_t k) {
        return glm::min(placeRects[k], glm::ivec4(width, height, width, height));
    };
    // A splat block is NEAR_SPLAT_BLOCK pixels a side, a trace block the trace's side.
    const auto sideOf = [&](bool cellRate) {
        return cellRate ? int(NEAR_SPLAT_BLOCK) : int(traceShape.side);
    };
    const auto blockCount = [&](std::size_t k, int side) -> std::uint64_t {
        const glm::ivec4 r = rectOf(k);
        if (r.z <= r.x || r.w <= r.y) return 0;
        const auto b = std::uint64_t(side);
        return (std::uint64_t(r.z - r.x) + b - 1) / b * ((std::uint64_t(r.w - r.y) + b - 1) / b);
    };
    // Per sprite of `visible` (0 where unranked): its counts, then their prefix sums.
    tileStart.resize(n + 1);
    splatStart.resize(n + 1);
    traceStart.resize(n + 1);
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, n, kSpriteGrain), [&](const auto& r) {
        for (std::size_t k = r.begin(); k != r.end(); ++k) {
            tileStart[k + 1] = splatStart[k + 1] = traceStart[k + 1] = 0;
            if (ranks[k] == near_gpu::NEAR_NO_RANK) continue;
            const bool cellRate = plan.cellBase[k] != kNoCells;
            const std::uint64_t nb = blockCount(k, sideOf(cellRate));
            if (cellRate) {
                tileStart[k + 1] = (placeWishes[k].cells + near_gpu::NEAR_CELL_TILE - 1) /
                                   near_gpu::NEAR_CELL_TILE;
                splatStart[k + 1] = nb;
            } else {
                traceStart[k + 1] = nb;
            }
        }
    });
    runningTotals(tileStart, chunkSums);
    runningTotals(splatStart, chunkSums);
    runningTotals(traceStart, chunkSums);
    tiles.resize(std::size_t(tileStart[n]));
    blocks.resize(std::size_t(splatStart[n] + traceStart[n]));
    // The trace's blocks follow the splat's in the same buffer.
    const std::uint64_t traceBase = splatStart[n];
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, n, kSpriteGrain), [&](const auto& range) {
        for (std::size_t k = range.begin(); k != range.end(); ++k) {
            if (ranks[k] == near_gpu::NEAR_NO_RANK) continue;
            const bool cellRate = plan.cellBase[k] != kNoCells;
            for (std::uint64_t t = tileStart[k]; t < tileStart[k + 1]; ++t)
                tiles[std::size_t(t)] = {
                    std::uint32_t(k), std::uint32_t((t - tileStart[k]) * near_gpu::NEAR_CELL_TILE)};
            const glm::ivec4 r = rectOf(k);
            if (r.z <= r.x || r.w <= r.y) continue;
            const std::uint32_t end = std::uint32_t(r.z) | std::uint32_t(r.w) << 16;
            std::size_t at = std::size_t(cellRate ? splatStart[k] : traceBase + traceStart[k]);
            const int side = sideOf(cellRate);
            for (int y = r.y; y < r.w; y += side)
                for (int x = r.x; x < r.z; x += side)
                    blocks[at++] = {std::uint32_t(k), std::uint32_t(x) | std::uint32_t(y) << 16,
                                    end, ranks[k]};
            // Read before written: the image's ~500 tile flags share a few cache lines, and each
            // of ~88,000 sprites (100,000 tanks) marks its tiles. Every store takes its line from
            // the other cores, where a load of a flag already set leaves the line shared.
            for (int ty = r.y / int(NEAR_SPLAT_BLOCK); ty <= (r.w - 1) / int(NEAR_SPLAT_BLOCK);
                 ++ty)
                for (int tx = r.x / int(NEAR_SPLAT_BLOCK); tx <= (r.z - 1) / int(NEAR_SPLAT_BLOCK);
                     ++tx) {
                    std::atomic_ref<std::uint8_t> flag(
                        touched[std::size_t(ty) * std::size_t(tilesX) + std::size_t(tx)]);
                    if (!flag.load(std::memory_order_relaxed))
                        flag.store(1, std::memory_order_relaxed);
                }
        }
    });
    const std::uint32_t splatCount = std::uint32_t(splatStart[n]);
    const std::uint32_t traceCount = std::uint32_t(traceStart[n]);
    // The resolve's tiles follow the trace's blocks.
    const std::uint32_t imageEnd = std::uint32_t(width) | std::uint32_t(height) << 16;
    for (int ty = 0; ty < tilesY; ++ty)
        for (int tx = 0; tx < tilesX; ++tx)
            if (touched[std::size_t(ty) * std::size_t(tilesX) + std::size_t(tx)])
                blocks.push_back({0,
                                  std::uint32_t(tx) * NEAR_SPLAT_BLOCK |
                                      (std::uint32_t(ty) * NEAR_SPLAT_BLOCK) << 16,
                                  imageEnd, 0});
    return {std::uint32_t(tiles.size()), splatCount, traceCount,
            std::uint32_t(blocks.size()) - splatCount - traceCount};
}

void NearPasses::Impl::writeDescriptors(GpuFrame& frame, Slot& slot) {
    // Rewritten every frame: cheap, and the slot's set is idle (its last frame has finished).
    using namespace near_gpu;
    if (!pixelWords || pixelWords.size() < frame.planeBytes()) {
        if (pixelWords) frame.keepUntilDone(std::move(pixelWords)); // as the cell store
        pixelWords =
            VulkanBuffer(device, frame.planeBytes(),
                         VK_BUFFER_USAGE_STORAGE_BUFFER_BIT | VK_BUFFER_USAGE_TRANSFER_DST_BIT,
                         BufferClass::DeviceOnly);
    }
    const VkDescriptorImageInfo atlasInfo{sampler, residency.atlasView(),
                                          VK_IMAGE_LAYOUT_SHADER_READ_ONLY_OPTIMAL};
    struct Binding {
        std::uint32_t binding;
        VkBuffer buffer;
    };
    const Binding buffers[] = {
        {NEAR_BINDING_SPRITES, slot.sprites.handle()},
        {NEAR_BINDING_PALETTES, residency.paletteBuffer()},
        {NEAR_BINDING_COUNTERS, slot.counters.handle()},
        {NEAR_BINDING_BOXES, slot.boxes.handle()},
        {NEAR_BINDING_HULLS, slot.hulls.handle()},
        {NEAR_BINDING_CELL_BASES, slot.cellBases.handle()},
        {NEAR_BINDING_CELLS, cells.handle()},
        {NEAR_BINDING_CELL_TILES, slot.cellTiles.handle()},
        {NEAR_BINDING_SPLAT_BLOCKS, slot.splatBlocks.handle()},
        {NEAR_BINDING_RANK_SPRITES, slot.rankSprites.handle()},
        {NEAR_BINDING_PIXEL_WORDS, pixelWords.handle()},
        {NEAR_BINDING_PLANES, frame.planes()},
        {NEAR_BINDING_BRICKS, residency.brickBuffer()},
        {NEAR_BINDING_RECORD_OF, slot.recordOf.handle()},
    };
    constexpr std::size_t kBuffers = std::size(buffers);
    VkDescriptorBufferInfo infos[kBuffers];
    VkWriteDescriptorSet w[kBuffers + 1]{};
    for (std::size_t i = 0; i < kBuffers; ++i) {
        infos[i] = {buffers[i].buffer, 0, VK_WHOLE_SIZE};
        w[i].sType = VK_STRUCTURE_TYPE_WRITE_DESCRIPTOR_SET;
        w[i].dstSet = slot.set;
        w[i].dstBinding = buffers[i].binding;
        w[i].descriptorCount = 1;
        w[i].descriptorType = VK_DESCRIPTOR_TYPE_STORAGE_BUFFER;
        w[i].pBufferInfo = &infos[i];
    }
    w[kBuffers].sType = VK_STRUCTURE_TYPE_WRITE_DESCRIPTOR_SET;
    w[kBuffers].dstSet = slot.set;
    w[kBuffers].dstBinding = NEAR_BINDING_ATLAS;
    w[kBuffers].descriptorCount = 1;
    w[kBuffers].descriptorType = VK_DESCRIPTOR_TYPE_COMBINED_IMAGE_SAMPLER;
    w[kBuffers].pImageInfo = &atlasInfo;
    vkUpdateDescriptorSets(device.device(), std::uint32_t(kBuffers + 1), w, 0, nullptr);
}

// ---------------------------------------------------------------------------------------------
// The passes

void NearPasses::Impl::dispatch(GpuFrame& frame, Slot& slot, ComputePass pass, std::uint32_t groups,
                                std::uint32_t first) {
    // A list of workgroups, as a 2D grid when there are more than one dimension allows.
    const std::uint32_t maxX = device.properties().limits.maxComputeWorkGroupCount[0];
    const std::uint32_t groupsX = std::min(groups, maxX);
    VkCommandBuffer cb = frame.commandBuffer();
    vkCmdBindPipeline(cb, VK_PIPELINE_BIND_POINT_COMPUTE, computePipeline(pass));
    vkCmdBindDescriptorSets(cb, VK_PIPELINE_BIND_POINT_COMPUTE, pipelineLayout, 0, 1, &slot.set, 0,
                            nullptr);
    const near_gpu::NearComputePush push{groups, std::uint32_t(frame.width()),
                                         std::uint32_t(frame.height()), frameCells, first};
    vkCmdPushConstants(cb, pipelineLayout, VK_SHADER_STAGE_COMPUTE_BIT, 0, sizeof push, &push);
    vkCmdDispatch(cb, groupsX, (groups + groupsX - 1) / groupsX, 1);
}

void NearPasses::Impl::recordWords(GpuFrame& frame, Slot& slot, CellWork work) {
    VkCommandBuffer cb = frame.commandBuffer();
    const auto cellsWritten = [&] {
        bufferBarrier(cb, cells.handle(), VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT,
                      VK_ACCESS_SHADER_WRITE_BIT, VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT,
                      VK_ACCESS_SHADER_READ_BIT | VK_ACCESS_SHADER_WRITE_BIT);
    };
    if (work.tiles) {
        frame.timer().begin(cb, "near_cells");
        dispatch(frame, slot, TraceCells, work.tiles);
        cellsWritten(); // the outline pass reads the primaries
        dispatch(frame, slot, Outline, work.tiles);
        frame.timer().end(cb);
    }
    if (!work.resolveTiles) return;
    frame.timer().begin(cb, "near_splat");
    vkCmdFillBuffer(cb, pixelWords.handle(), 0, frame.planeBytes(), near_gpu::NEAR_NO_RANK);
    // The splat reads the outcomes and min-writes the cleared words.
    if (work.tiles) cellsWritten();
    bufferBarrier(cb, pixelWords.handle(), VK_PIPELINE_STAGE_TRANSFER_BIT,
                  VK_ACCESS_TRANSFER_WRITE_BIT, VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT,
                  VK_ACCESS_SHADER_READ_BIT | VK_ACCESS_SHADER_WRITE_BIT);
    if (work.blocks) dispatch(frame, slot, Splat, work.blocks);
    frame.timer().end(cb);
    if (!work.traceBlocks) return;
    // The trace reads the splat's words to skip the pixels a nearer sprite holds.
    bufferBarrier(cb, pixelWords.handle(), VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT,
                  VK_ACCESS_SHADER_WRITE_BIT, VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT,
                  VK_ACCESS_SHADER_READ_BIT | VK_ACCESS_SHADER_WRITE_BIT);
    frame.timer().begin(cb, "near_trace");
    dispatch(frame, slot, TracePixels, work.traceBlocks, work.blocks);
    frame.timer().end(cb);
}

void NearPasses::Impl::ensureFramebuffer(GpuFrame& frame) {
    // The frames' targets are re-created when the image size changes (GpuFrames::begin waits for
    // every frame first), and with them their views.
    if (framebuffer && framebufferColor == frame.color().view()) return;
    if (framebuffer) vkDestroyFramebuffer(device.device(), framebuffer, nullptr);
    framebuffer = VK_NULL_HANDLE;
    const VkImageView views[3] = {frame.color().view(), frame.id().view(), frame.depth().view()};
    VkFramebufferCreateInfo fci{VK_STRUCTURE_TYPE_FRAMEBUFFER_CREATE_INFO};
    fci.renderPass = renderPass;
    fci.attachmentCount = 3;
    fci.pAttachments = views;
    fci.width = std::uint32_t(frame.width());
    fci.height = std::uint32_t(frame.height());
    fci.layers = 1;
    VK_CHECK(vkCreateFramebuffer(device.device(), &fci, nullptr, &framebuffer));
    framebufferColor = frame.color().view();
}

void NearPasses::Impl::recordDraw(GpuFrame& frame, Slot& slot, Rgba8 clear, bool allPlanes,
                                  const NearOptions& opt, NearStats& stats) {
    VkCommandBuffer cb = frame.commandBuffer();
    const std::uint32_t n = std::uint32_t(visible.size());
    const bool query = opt.pipelineStatistics && slot.statsPool && n;
    slot.queried = query;
    if (query) vkCmdResetQueryPool(cb, slot.statsPool, 0, 1);
    ensureFramebuffer(frame);
    frame.timer().begin(cb, "near_draw");
    VkClearValue clears[3]{};
    clears[0].color.uint32[0] = clear;
    clears[1].color.uint32[0] = kernel::VT_NO_ENTITY;
    clears[2].depthStencil = {0.0f, 0}; // reversed-Z: 0 = infinitely far, nothing drawn
    VkRenderPassBeginInfo rbi{VK_STRUCTURE_TYPE_RENDER_PASS_BEGIN_INFO};
    rbi.renderPass = renderPass;
    rbi.framebuffer = framebuffer;
    rbi.renderArea = {{0, 0}, {std::uint32_t(frame.width()), std::uint32_t(frame.height())}};
    rbi.clearValueCount = 3;
    rbi.pClearValues = clears;
    vkCmdBeginRenderPass(cb, &rbi, VK_SUBPASS_CONTENTS_INLINE);
    vkCmdBindDescriptorSets(cb, VK_PIPELINE_BIND_POINT_GRAPHICS, pipelineLayout, 0, 1, &slot.set, 0,
                            nullptr);
    const VkViewport viewport{0.0f, 0.0f, float(frame.width()), float(frame.height()), 0.0f, 1.0f};
    const VkRect2D scissor{{0, 0}, {std::uint32_t(frame.width()), std::uint32_t(frame.height())}};
    vkCmdSetViewport(cb, 0, 1, &viewport);
    vkCmdSetScissor(cb, 0, 1, &scissor);
    if (query) vkCmdBeginQuery(cb, slot.statsPool, 0, 0);
    const std::uint32_t vertices = opt.proxy == NearProxy::Box    ? near_gpu::NEAR_BOX_VERTICES
                                   : opt.proxy == NearProxy::Hull ? near_gpu::NEAR_HULL_VERTICES
                                                                  : near_gpu::NEAR_QUAD_VERTICES;
    // One instanced draw per stretch of sprites with the same depth source, in order
    // (gl_InstanceIndex counts from firstInstance, so it still indexes the sprite buffers).
    for (std::uint32_t first = 0; first < n;) {
        std::uint32_t end = first + 1;
        while (end < n && flat[end] == flat[first]) ++end;
        vkCmdBindPipeline(cb, VK_PIPELINE_BIND_POINT_GRAPHICS,
                          pipeline(opt.proxy, opt.countSteps, flat[first] != 0));
        if (opt.draws == NearDraws::Instanced) {
            vkCmdDraw(cb, vertices, end - first, 0, first);
            stats.drawCalls += 1;
        } else {
            // Same order, one draw each: gl_InstanceIndex = firstInstance selects it.
            for (std::uint32_t i = first; i < end; ++i) vkCmdDraw(cb, vertices, 1, 0, i);
            stats.drawCalls += end - first;
        }
        first = end;
    }
    if (query) vkCmdEndQuery(cb, slot.statsPool, 0);
    vkCmdEndRenderPass(cb);
    frame.timer().end(cb);
    frame.timer().begin(cb, "copy_planes");
    frame.recordTargetsToPlanes(allPlanes);
    frame.timer().end(cb);
}

void NearPasses::Impl::recordResolve(GpuFrame& frame, Slot& slot, CellWork work) {
    // After the drawn targets are in the planes and the splat has finished (both earlier in
    // this command buffer).
    VkCommandBuffer cb = frame.commandBuffer();
    bufferBarrier(cb, pixelWords.handle(), VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT,
                  VK_ACCESS_SHADER_WRITE_BIT, VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT,
                  VK_ACCESS_SHADER_READ_BIT);
    frame.timer().begin(cb, "near_resolve");
    dispatch(frame, slot, Resolve, work.resolveTiles, work.blocks + work.traceBlocks);
    frame.timer().end(cb);
    bufferBarrier(
        cb, frame.planes(), VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT, VK_ACCESS_SHADER_WRITE_BIT,
        VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT | VK_PIPELINE_STAGE_TRANSFER_BIT,
        VK_ACCESS_SHADER_READ_BIT | VK_ACCESS_SHADER_WRITE_BIT | VK_ACCESS_TRANSFER_READ_BIT);
}

// ---------------------------------------------------------------------------------------------

NearPasses::NearPasses(GpuFrames& frames) : impl_(std::make_unique<Impl>(frames)) {}
NearPasses::~NearPasses() = default;

const VoxelResidency& NearPasses::residency() const {
    return impl_->residency;
}

void NearPasses::record(GpuFrame& frame, const CameraFrame& cam,
                        const std::vector<std::shared_ptr<VoxelModel>>& models,
                        std::span<const SpriteSetup* const> sprites, Rgba8 clear,
                        const NearOptions& opt, NearStats& stats, const SpriteHistory* history) {
    Impl& m = *impl_;
    Impl::Slot& slot = m.slots.at(std::size_t(frame.slot()));
    slot.queried = false; // the draw's statistics query, when the frame draws
    m.skipEmpty = opt.skipEmpty;
    m.countSteps = opt.countSteps;
    VkCommandBuffer cb = frame.commandBuffer();
    frame.timer().begin(cb, "near_upload");
    // The resolve pass binds the whole planes buffer; past the device's storage-buffer range (a
    // huge image) every sprite is traced per pixel by the draw. The ranks of a pixel word hold
    // at most NEAR_MAX_CELL_SPRITES sprites; a frame of more draws its per-pixel sprites.
    const bool resolvable =
        3 * frame.planeBytes() <= m.device.properties().limits.maxStorageBufferRange;
    const NearRate rate = resolvable ? opt.rate : NearRate::Fragment;
    const auto tSprites = std::chrono::steady_clock::now();
    m.writeSprites(frame, slot, models, sprites, opt, rate, stats, history);
    stats.recordSpritesMs = msSince(tSprites);
    const auto tLists = std::chrono::steady_clock::now();
    // Auto: llvmpipe rasterises a crowd under the early depth test faster than it runs the
    // trace's workgroups over every rectangle (100,000 tanks: 2.7 s against 8.0 s); a GPU the
    // other way round (docs/decisions/near-pixels-in-compute.md).
    const NearPixels pixels = opt.pixels != NearPixels::Auto ? opt.pixels
                              : m.device.isCpu()             ? NearPixels::Raster
                                                             : NearPixels::Compute;
    const bool tracePixels = pixels == NearPixels::Compute && resolvable &&
                             m.visible.size() <= near_gpu::NEAR_MAX_CELL_SPRITES;
    stats.pixelsInCompute = tracePixels;
    if (opt.countSteps && !tracePixels && !m.device.hasFragmentAtomics())
        throw VulkanError("near tier: counting DDA steps needs fragmentStoresAndAtomics, which " +
                          m.device.name() + " lacks");
    if (!tracePixels) m.writeProxies(frame, slot, cam, opt, stats);
    CellRatePlan& plan = m.ratePlan;
    stats.recordListsUploadMs = 0.0; // summed over the lists' uploads (writeCells)
    const auto tPlan = std::chrono::steady_clock::now();
    planCellRate(m.placeWishes, plan, opt.cellBudgetBytes);
    stats.recordListsBuildMs = msSince(tPlan);
    stats.cellsTraced = plan.cells;
    stats.cellSprites = plan.cellSprites;
    stats.cellOverBudget = plan.overBudget;
    stats.pixelsTraced = plan.pixelsTraced;
    stats.pixelsLookedUp = plan.pixelsLookedUp;
    m.traceShape = nearTraceShape(m.device, tracePixels ? m.visible.size() - plan.cellSprites : 0);
    const Impl::CellWork work =
        m.writeCells(frame, slot, plan, opt.cellBudgetBytes, tracePixels, stats);
    m.frameCells = std::uint32_t(plan.cells);
    m.writeDescriptors(frame, slot);
    stats.recordListsMs = msSince(tLists);
    frame.ring().recordBarrier(cb,
                               VK_PIPELINE_STAGE_VERTEX_SHADER_BIT |
                                   VK_PIPELINE_STAGE_FRAGMENT_SHADER_BIT |
                                   VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT,
                               VK_ACCESS_SHADER_READ_BIT);
    frame.timer().end(cb);

    // Cell-rate sprites: every cell traced once, then every pixel of theirs splatted; per-pixel
    // sprites traced in compute leave their words next. The draw skips them all; the resolve
    // after it shades them.
    // The counting variants (the trace's or the fragment shader's) add to counters zeroed here,
    // so that a frame with nothing to count reads 0.
    const VkPipelineStageFlags counting =
        VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT | VK_PIPELINE_STAGE_FRAGMENT_SHADER_BIT;
    if (opt.countSteps) {
        vkCmdFillBuffer(cb, slot.counters.handle(), 0, VK_WHOLE_SIZE, 0);
        bufferBarrier(cb, slot.counters.handle(), VK_PIPELINE_STAGE_TRANSFER_BIT,
                      VK_ACCESS_TRANSFER_WRITE_BIT, counting | VK_PIPELINE_STAGE_HOST_BIT,
                      VK_ACCESS_SHADER_READ_BIT | VK_ACCESS_SHADER_WRITE_BIT |
                          VK_ACCESS_HOST_READ_BIT);
    }
    m.recordWords(frame, slot, work);
    // Depth and ids are needed where the resolve composes by them, or someone reads them (the
    // caller asks for them where a far pass follows).
    const bool allPlanes = opt.readDepthAndIds || work.resolveTiles;
    const bool rasterised = !tracePixels && plan.cellSprites < m.visible.size();
    if (rasterised)
        m.recordDraw(frame, slot, clear, allPlanes, opt, stats);
    else
        frame.recordClearPlanes(clear, allPlanes);
    if (work.resolveTiles) m.recordResolve(frame, slot, work);
    if (opt.countSteps)
        bufferBarrier(cb, slot.counters.handle(), counting, VK_ACCESS_SHADER_WRITE_BIT,
                      VK_PIPELINE_STAGE_HOST_BIT, VK_ACCESS_HOST_READ_BIT);
}

void NearPasses::collect(GpuFrame& frame, const NearOptions& opt, NearStats& stats) {
    Impl& m = *impl_;
    frame.wait();
    Impl::Slot& slot = m.slots.at(std::size_t(frame.slot()));
    if (slot.queried) {
        std::uint64_t invocations = 0;
        VK_CHECK(vkGetQueryPoolResults(m.device.device(), slot.statsPool, 0, 1, sizeof invocations,
                                       &invocations, sizeof invocations,
                                       VK_QUERY_RESULT_64_BIT | VK_QUERY_RESULT_WAIT_BIT));
        stats.fragmentInvocations = invocations;
    }
    if (opt.countSteps) {
        slot.counters.invalidateForRead();
        const auto* c = static_cast<const near_gpu::NearCounters*>(slot.counters.mapped());
        stats.voxelFetches = (std::uint64_t(c->fetchesHi) << 32) | c->fetchesLo;
        stats.kernelFragments = (std::uint64_t(c->fragmentsHi) << 32) | c->fragmentsLo;
    }
}

} // namespace voxtier
