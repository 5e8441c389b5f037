#pragma once
// Internal to volumetric (not installed): the state of NearPasses, shared by the file that creates
// its Vulkan objects (near_passes_create.cpp) and the one that records a frame's passes
// (near_passes.cpp).
#include "core/near_rate.hpp"
#include "core/occlusion.hpp"
#include "volumetric/near_passes.hpp"
#include "volumetric/near_pipelines.hpp"
#include "volumetric/shaders/near_shared.h"
#include "volumetric/voxel_residency.hpp"

#include <array>
#include <cstdint>
#include <map>
#include <span>
#include <utility>
#include <vector>

namespace voxtier {

struct NearPasses::Impl {
    GpuFrames& frames;
    VulkanDevice& device;
    VoxelResidency residency;

    VkSampler sampler = VK_NULL_HANDLE;
    VkDescriptorSetLayout setLayout = VK_NULL_HANDLE;
    VkPipelineLayout pipelineLayout = VK_NULL_HANDLE;
    VkDescriptorPool descriptorPool = VK_NULL_HANDLE;
    VkRenderPass renderPass = VK_NULL_HANDLE;
    /// [proxy][countSteps][flatDepth][skipEmpty], created on first use
    VkPipeline pipelines[3][2][2][2] = {};
    /// NearComputePass's values, as indices.
    enum ComputePass { TraceCells, Outline, Splat, TracePixels, Resolve, ComputePassCount };
    /// [pass][skipEmpty] (only the tracing passes have a skipping variant), created on first
    /// use; TracePixels' are in tracePipelines.
    VkPipeline computePipelines[ComputePassCount][2] = {};
    /// The trace's pipelines by workgroup shape (side, rows): [skipEmpty * 2 + countSteps].
    std::map<std::pair<std::uint32_t, std::uint32_t>, std::array<VkPipeline, 4>> tracePipelines;
    /// This frame's NearOptions::skipEmpty and countSteps: which variant the pipelines take.
    bool skipEmpty = false;
    bool countSteps = false;
    /// This frame's trace workgroup (nearTraceShape).
    NearTraceShape traceShape;

    // Shared by the slots (the frame-start barrier orders their use): the framebuffer over the
    // frames' targets, the cell store (grown up to the budget) and the splat's pixel words.
    VkFramebuffer framebuffer = VK_NULL_HANDLE;
    VkImageView framebufferColor = VK_NULL_HANDLE;
    VulkanBuffer cells, pixelWords;

    /// What a slot's sprite buffer holds, where it was written from a store's sprites: as of
    /// which update of which store, with which rate and placements, and per record the
    /// entity whose record it is (kNoEntity: a copy's, not drawn, or unknown) with what the lists
    /// read of it (Impl::placeDepths, placeRects and placeWishes in the draw order).
    struct KeptRecords {
        static constexpr std::uint32_t kNoEntity = SpriteHistory::kNoEntity;
        std::uint64_t store = 0, asOf = 0; ///< store 0: nothing kept
        NearRate rate = NearRate::Auto;
        VkBuffer buffer = VK_NULL_HANDLE; ///< a grown buffer holds nothing
        VoxelResidency::Placements placements;
        std::vector<std::uint32_t> entity;
        std::vector<float> depths;
        std::vector<glm::ivec4> rects;
        std::vector<CellRateWish> wishes;
    };
    /// Per frame in flight: what the host writes for a frame, its descriptor set and queries.
    struct Slot {
        /// sprites: the records, laid out by NearRecords; recordOf: each draw place's record.
        VulkanBuffer sprites, recordOf, boxes, hulls, cellBases, cellTiles, splatBlocks,
            rankSprites;
        VulkanBuffer counters; ///< written by the counting shader, read by the host
        VkDescriptorSet set = VK_NULL_HANDLE;
        VkQueryPool statsPool = VK_NULL_HANDLE;
        bool queried = false; ///< this slot's last frame ran the statistics query
        KeptRecords kept;
    };
    std::vector<Slot> slots;

    // The frame being recorded (host scratch, reused from frame to frame).
    std::vector<const SpriteSetup*> visible;
    /// The last draw order from a store's sprites (the early depth test's front to back): each
    /// sprite's entity in the order given (kNoEntity: a copy), and the order as places in it.
    struct KeptOrder {
        std::uint64_t store = 0, asOf = 0; ///< store 0: nothing kept
        std::vector<std::uint32_t> entity, order;
        DrawOrderBuffers buffers; ///< the order's working arrays (kept for their storage)
    } keptOrder;
    /// The residency's first showings of last frame's `visible`: kept while its sprites are the
    /// same entities', in the same order, at the same animation frames.
    VoxelResidency::FirstShowings firstShowings;
    /// Per sprite given, its place in `visible` (VoxelResidency::kNotShown: not drawn), from which
    /// a frame whose order changed finds its first showings (kept for its storage).
    std::vector<std::uint32_t> places;
    /// Where each resident model frame lies, looked up once a frame (kept for its storage).
    VoxelResidency::Placements placements;
    /// Per sprite of `visible`, its depth, screen rectangle and rate wish: the slot's kept arrays
    /// where the records lie in the draw order, else gathered from them into the `gathered`
    /// arrays after the records are written (in parallel). The ranking, the rate plan and the
    /// work lists read these and not each sprite's record again (at 100,000 sprites a record read
    /// is a cache miss apiece, and each pass over them cost milliseconds).
    std::span<const float> placeDepths;
    std::span<const glm::ivec4> placeRects;
    std::span<const CellRateWish> placeWishes;
    std::vector<float> gatheredDepths;
    std::vector<glm::ivec4> gatheredRects;
    std::vector<CellRateWish> gatheredWishes;
    /// This frame's cell-rate plan (kept for its storage).
    CellRatePlan ratePlan;
    std::vector<std::uint8_t> flat;
    std::vector<glm::uvec2> tiles;
    std::vector<near_gpu::NearSplatBlock> blocks;
    /// Per sprite of `visible`, the first of its cell tiles, splat blocks and trace blocks (a
    /// prefix sum: entry n is the total).
    std::vector<std::uint64_t> tileStart, splatStart, traceStart;
    std::vector<std::uint32_t> byDepth, ranks;
    std::vector<std::uint8_t> touched;
    /// Scratch of the lists' chunked passes (where runningTotalsInParallel): per chunk of
    /// sprites a count or a running total, and whether its ranked sprites are in depth order.
    std::vector<std::uint64_t> chunkSums;
    std::vector<std::uint8_t> chunkSorted;
    std::uint32_t frameCells = 0;

    /// The compute passes' workgroups; the blocks buffer holds the splat's, then the trace's,
    /// then the resolve's.
    struct CellWork {
        std::uint32_t tiles = 0;        ///< near_cells.comp workgroups
        std::uint32_t blocks = 0;       ///< near_splat.comp workgroups
        std::uint32_t traceBlocks = 0;  ///< near_trace.comp workgroups
        std::uint32_t resolveTiles = 0; ///< near_resolve.comp workgroups (0: no words to resolve)
    };

    explicit Impl(GpuFrames& f)
        : frames(f), device(f.device()), residency(f.device(), [&f] { f.waitAll(); }) {
        try {
            create();
        } catch (...) {
            destroy();
            throw;
        }
    }
    ~Impl() { destroy(); }

    void create();
    void createLayouts();
    void createRenderPass();
    void createSlot(Slot& s);
    void destroy() noexcept;
    VkPipeline pipeline(NearProxy proxy, bool countSteps, bool flatDepth);
    VkPipeline computePipeline(ComputePass pass);
    /// Grows `b` (a ShaderRead buffer of the slot) to hold `bytes`, doubling.
    void ensure(VulkanBuffer& b, VkDeviceSize bytes, BufferClass c = BufferClass::ShaderRead);

    /// The sprites in draw order, their residency, their per-sprite data written for the frame
    /// (what `history` shows the slot holds as it is now, left as it is).
    void writeSprites(GpuFrame& frame, Slot& slot,
                      const std::vector<std::shared_ptr<VoxelModel>>& models,
                      std::span<const SpriteSetup* const> all, const NearOptions& opt,
                      NearRate rate, NearStats& stats, const SpriteHistory* history);
    /// `visible` in draw order: last frame's, where `all` are the same entities' sprites and
    /// none was set up anew since (true), else sorted afresh. `unchanged`: whether, besides,
    /// none changed at all since (the same animation frames too).
    bool orderSprites(std::span<const SpriteSetup* const> all, const NearOptions& opt,
                      const SpriteHistory* history, bool& unchanged);
    void writeProxies(GpuFrame& frame, Slot& slot, const CameraFrame& cam, const NearOptions& opt,
                      NearStats& stats);
    /// The compute passes' work; with `tracePixels` the per-pixel sprites' blocks too, and every
    /// sprite ranked. Its host arithmetic and its uploads are timed into `stats`
    /// (recordListsBuildMs, recordListsUploadMs).
    CellWork writeCells(GpuFrame& frame, Slot& slot, const CellRatePlan& plan,
                        std::uint64_t budgetBytes, bool tracePixels, NearStats& stats);
    /// byDepth and ranks: the ranked sprites (cell-rate, and with `tracePixels` all) in
    /// Image::writeIfNearer's order, and each one's place in it.
    void rankSprites(const CellRatePlan& plan, bool tracePixels);
    /// writeCells' lists: ranks, cell tiles, splat and trace blocks, resolve tiles.
    CellWork buildWorkLists(const CellRatePlan& plan, bool tracePixels, int width, int height);
    void writeDescriptors(GpuFrame& frame, Slot& slot);
    void dispatch(GpuFrame& frame, Slot& slot, ComputePass pass, std::uint32_t groups,
                  std::uint32_t first = 0);
    /// The cells, the splat and the trace: every pass that leaves pixel words.
    void recordWords(GpuFrame& frame, Slot& slot, CellWork work);
    /// The raster pass, then its attachments into the planes (all three when `allPlanes`).
    void recordDraw(GpuFrame& frame, Slot& slot, Rgba8 clear, bool allPlanes,
                    const NearOptions& opt, NearStats& stats);
    void recordResolve(GpuFrame& frame, Slot& slot, CellWork work);
    void ensureFramebuffer(GpuFrame& frame);
};

} // namespace voxtier
