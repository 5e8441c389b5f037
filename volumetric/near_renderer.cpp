#include "volumetric/near_renderer.hpp"

#include "core/occlusion.hpp"
#include "core/stopwatch.hpp"
#include "volumetric/far_residency.hpp"
#include "volumetric/shaders/far_shared.h"
#include "volumetric/shaders/near_shared.h"
#include "volumetric/voxel_residency.hpp"
#include "device/vulkan_device.hpp"

#include <algorithm>
#include <chrono>
#include <cstdint>
#include <cstring>
#include <unordered_map>

// SPIR-V generated at build time by glslangValidator (volumetric/CMakeLists.txt).
#include "shaders/far_blit_comp.h"
#include "shaders/near_box_vert.h"
#include "shaders/near_cell_outline_comp.h"
#include "shaders/near_cells_comp.h"
#include "shaders/near_flat_frag.h"
#include "shaders/near_flat_steps_frag.h"
#include "shaders/near_frag.h"
#include "shaders/near_hull_vert.h"
#include "shaders/near_quad_vert.h"
#include "shaders/near_resolve_comp.h"
#include "shaders/near_splat_comp.h"
#include "shaders/near_steps_frag.h"

namespace voxtier {

namespace {

using Clock = std::chrono::steady_clock;

// The plan's marker and the shaders' marker are one value: near_shared.h is not installed with
// the public near_rate.hpp, so the two spellings are tied here instead of by an include.
static_assert(kNoCells == near_gpu::NEAR_NO_CELLS);
static_assert(kMaxCellSprites == near_gpu::NEAR_MAX_CELL_SPRITES);

constexpr VkFormat kColorFormat = VK_FORMAT_R32_UINT; // packed RGBA8 from the kernel, bit-exact
constexpr VkFormat kIdFormat = VK_FORMAT_R32_UINT;
constexpr VkFormat kDepthFormat = VK_FORMAT_D32_SFLOAT; // the kernel's float depth, stored as is

} // namespace

std::array<glm::dvec4, 8> NearRenderer::proxyBoxClipCorners(const CameraFrame& cam,
                                                            const SpriteSetup& s) {
    // §3.10: model bounds grown by one virtual pixel (1/sigma voxel) on every side.
    const double m = 1.0 / s.lattice.sigma;
    const glm::dvec3 lo(-m), hi = glm::dvec3(s.lattice.dims) + m;
    std::array<glm::dvec4, 8> out;
    for (int k = 0; k < 8; ++k) {
        const glm::dvec3 p{(k & 1) ? hi.x : lo.x, (k & 2) ? hi.y : lo.y, (k & 4) ? hi.z : lo.z};
        out[std::size_t(k)] = clipFromCameraRelative(cam, s.pose.relativeWorld(p, cam.eye));
    }
    return out;
}

std::vector<glm::dvec4> NearRenderer::proxyHullClipCorners(const CameraFrame& cam,
                                                           const SpriteSetup& s) {
    const SpriteLattice& L = s.lattice;
    const double k = s.pose.metresPerVoxel;
    // A pixel can be non-empty only if its sprite-plane point lies in a cell whose centre, or a
    // cardinal neighbour's centre, sends a parallel ray into the model box [0, N]^3, i.e. within
    // 1.5 cells (per axis) of the box's parallel projection H. Two pixels more (measured at the
    // centre's depth, an over-estimate of a pixel on the plane near the sprite) keep the
    // rasteriser's rounding away from every pixel that matters, as with the quad (DESIGN §3.10).
    const double m = 1.5 / L.sigma + 2.0 * cam.pixelScale() * s.viewDepth / k;
    std::vector<glm::dvec2> pts;
    pts.reserve(32);
    for (int c = 0; c < 8; ++c) {
        const glm::dvec3 p =
            glm::dvec3((c & 1) ? L.dims.x : 0, (c & 2) ? L.dims.y : 0, (c & 4) ? L.dims.z : 0) -
            L.centre;
        const double u = glm::dot(p, L.right), v = glm::dot(p, L.up);
        for (int q = 0; q < 4; ++q) pts.push_back({u + ((q & 1) ? m : -m), v + ((q & 2) ? m : -m)});
    }
    // Andrew's monotone chain; collinear points dropped, counter-clockwise order.
    std::sort(pts.begin(), pts.end(),
              [](glm::dvec2 a, glm::dvec2 b) { return a.x < b.x || (a.x == b.x && a.y < b.y); });
    auto cross = [](glm::dvec2 o, glm::dvec2 a, glm::dvec2 b) {
        return (a.x - o.x) * (b.y - o.y) - (a.y - o.y) * (b.x - o.x);
    };
    std::vector<glm::dvec2> hull(2 * pts.size());
    std::size_t h = 0;
    for (std::size_t i = 0; i < pts.size(); ++i) {
        while (h >= 2 && cross(hull[h - 2], hull[h - 1], pts[i]) <= 0.0) --h;
        hull[h++] = pts[i];
    }
    for (std::size_t i = pts.size() - 1, lower = h + 1; i-- > 0;) {
        while (h >= lower && cross(hull[h - 2], hull[h - 1], pts[i]) <= 0.0) --h;
        hull[h++] = pts[i];
    }
    hull.resize(h - 1); // the last point repeats the first
    std::vector<glm::dvec4> out;
    if (hull.size() > near_gpu::NEAR_HULL_MAX_VERTICES || hull.size() < 3) {
        // Cannot happen for a box (hexagon + square: at most 10 corners), but never draw less
        // than the quad: its corners in fan order.
        for (int i : {0, 1, 3, 2}) out.push_back(glm::dvec4(s.gpu.quad[i]));
        return out;
    }
    const glm::dvec3 rW = s.pose.worldDirection(L.right), uW = s.pose.worldDirection(L.up);
    for (glm::dvec2 p : hull)
        out.push_back(clipFromCameraRelative(cam, s.centreRel + k * (p.x * rW + p.y * uW)));
    return out;
}

struct NearRenderer::Impl {
    VulkanDevice device;
    VoxelResidency residency;
    FarResidency farResidency;

    VkSampler sampler = VK_NULL_HANDLE;
    VkDescriptorSetLayout setLayout = VK_NULL_HANDLE;
    VkPipelineLayout pipelineLayout = VK_NULL_HANDLE;
    VkDescriptorPool descriptorPool = VK_NULL_HANDLE;
    VkDescriptorSet descriptorSet = VK_NULL_HANDLE;
    VkRenderPass renderPass = VK_NULL_HANDLE;
    VkPipeline pipelines[3][2][2] = {}; ///< [proxy][countSteps][flatDepth], created on first use
    /// The cell-rate compute passes (trace, outline, splat, resolve), created on first use.
    enum ComputePass { TraceCells, Outline, Splat, Resolve, FarBlit, ComputePassCount };
    VkPipeline computePipelines[ComputePassCount] = {};
    VkQueryPool statsPool = VK_NULL_HANDLE;
    /// GPU times of the frame's one submission: frame start, trace + splat done; resolve start,
    /// resolve done; far pass start (its uploads), far pass done; readback copy start, done.
    static constexpr std::uint32_t kTimestamps = 8;
    VkQueryPool timePool = VK_NULL_HANDLE;
    VkCommandBuffer drawCb = VK_NULL_HANDLE;

    // Render targets, re-created when the image size changes; the readback buffer is also
    // where the resolve pass writes the cell-rate sprites, and pixelWords holds the splat's
    // least word per pixel (device-local).
    int width = 0, height = 0;
    VulkanImage color, id, depth;
    VkFramebuffer framebuffer = VK_NULL_HANDLE;
    VulkanBuffer readback, pixelWords;

    // Per-frame data (host-visible, coherent) and the step counters.
    VulkanBuffer sprites, boxes, hulls, counters;
    // Cell-rate (near_rate.hpp): per-sprite cell offsets, the compute tiles, the splat blocks
    // and the sprite of each depth rank (host-visible, written per frame), and the cell store
    // (device-local, grown up to the budget, reused).
    VulkanBuffer cellBases, cellTiles, splatBlocks, rankSprites, cells;
    std::uint32_t frameCells = 0; ///< cells of this frame's plan (where the outcomes start)
    // The far pass (far_shared.h): instances, palettes, tiles and tile lists (host-visible,
    // written per frame); the snapshots live in farResidency.
    VulkanBuffer farInstances, farPalettes, farTiles, farTileList;

    Impl(const VulkanDeviceOptions& options, std::shared_ptr<VulkanMessageLog> log)
        : device(options, std::move(log)), residency(device), farResidency(device) {
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
    VkPipeline pipeline(NearProxy proxy, bool countSteps, bool flatDepth);
    VkPipeline computePipeline(ComputePass pass);
    struct CellWork {
        std::uint32_t tiles = 0;        ///< near_cells.comp workgroups
        std::uint32_t blocks = 0;       ///< near_splat.comp workgroups (0: no resolve either)
        std::uint32_t resolveTiles = 0; ///< near_resolve.comp workgroups, after the blocks
    };
    /// Writes the per-sprite cell offsets, the compute tiles, the splat blocks and resolve tiles,
    /// and the sprite of each depth rank of `plan`.
    CellWork prepareCells(const CellRatePlan& plan, const std::vector<const SpriteSetup*>& visible,
                          std::uint64_t budgetBytes);
    /// Records one compute pass over `groups` workgroups (its push constant count).
    void dispatch(VkCommandBuffer cb, ComputePass pass, std::uint32_t groups,
                  std::uint32_t first = 0);
    void recordCellPasses(VkCommandBuffer cb, CellWork work);
    void recordResolve(VkCommandBuffer cb, CellWork work);
    /// Writes the far pass's instances, palettes and tiles for `batch` (uploads its new
    /// snapshots through farResidency). Returns the tiles to dispatch.
    std::uint32_t prepareFar(const FarBatch& batch, NearStats& stats);
    void ensureTargets(int w, int h);
    void ensureBuffer(VulkanBuffer& b, VkDeviceSize bytes, VkBufferUsageFlags usage,
                      bool hostVisible = true);
    void writeDescriptors();
    Image render(const CameraFrame& cam, const std::vector<std::shared_ptr<VoxelModel>>& models,
                 std::span<const SpriteSetup* const> sprites, Rgba8 background,
                 const NearOptions& opt, NearStats* stats);
};

void NearRenderer::Impl::create() {
    VkDevice dev = device.device();

    VkSamplerCreateInfo sci{VK_STRUCTURE_TYPE_SAMPLER_CREATE_INFO};
    // texelFetch ignores the sampler's filtering; nearest keeps the integer format legal.
    sci.magFilter = VK_FILTER_NEAREST;
    sci.minFilter = VK_FILTER_NEAREST;
    sci.mipmapMode = VK_SAMPLER_MIPMAP_MODE_NEAREST;
    sci.addressModeU = sci.addressModeV = sci.addressModeW = VK_SAMPLER_ADDRESS_MODE_CLAMP_TO_EDGE;
    VK_CHECK(vkCreateSampler(dev, &sci, nullptr, &sampler));

    using namespace near_gpu;
    const VkShaderStageFlags c = VK_SHADER_STAGE_COMPUTE_BIT;
    const VkShaderStageFlags fc = VK_SHADER_STAGE_FRAGMENT_BIT | c;
    const VkShaderStageFlags vfc = VK_SHADER_STAGE_VERTEX_BIT | fc;
    const VkShaderStageFlags vc = VK_SHADER_STAGE_VERTEX_BIT | c;
    const VkDescriptorSetLayoutBinding bindings[] = {
        {NEAR_BINDING_SPRITES, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, 1, vfc, nullptr},
        {NEAR_BINDING_ATLAS, VK_DESCRIPTOR_TYPE_COMBINED_IMAGE_SAMPLER, 1, fc, nullptr},
        {NEAR_BINDING_PALETTES, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, 1, fc, nullptr},
        {NEAR_BINDING_COUNTERS, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, 1, VK_SHADER_STAGE_FRAGMENT_BIT,
         nullptr},
        {NEAR_BINDING_BOXES, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, 1, VK_SHADER_STAGE_VERTEX_BIT,
         nullptr},
        {NEAR_BINDING_HULLS, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, 1, VK_SHADER_STAGE_VERTEX_BIT,
         nullptr},
        {NEAR_BINDING_CELL_BASES, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, 1, vc, nullptr},
        {NEAR_BINDING_CELLS, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, 1, c, nullptr},
        {NEAR_BINDING_CELL_TILES, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, 1, c, nullptr},
        {NEAR_BINDING_SPLAT_BLOCKS, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, 1, c, nullptr},
        {NEAR_BINDING_RANK_SPRITES, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, 1, c, nullptr},
        {NEAR_BINDING_PIXEL_WORDS, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, 1, c, nullptr},
        {NEAR_BINDING_READBACK, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, 1, c, nullptr},
        {NEAR_BINDING_FAR_INSTANCES, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, 1, c, nullptr},
        {NEAR_BINDING_FAR_SNAPSHOTS, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, 1, c, nullptr},
        {NEAR_BINDING_FAR_PALETTES, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, 1, c, nullptr},
        {NEAR_BINDING_FAR_TILES, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, 1, c, nullptr},
        {NEAR_BINDING_FAR_TILE_LIST, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, 1, c, nullptr},
        {NEAR_BINDING_BRICKS, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, 1, fc, nullptr},
    };
    VkDescriptorSetLayoutCreateInfo dli{VK_STRUCTURE_TYPE_DESCRIPTOR_SET_LAYOUT_CREATE_INFO};
    dli.bindingCount = std::uint32_t(std::size(bindings));
    dli.pBindings = bindings;
    VK_CHECK(vkCreateDescriptorSetLayout(dev, &dli, nullptr, &setLayout));

    VkPipelineLayoutCreateInfo pli{VK_STRUCTURE_TYPE_PIPELINE_LAYOUT_CREATE_INFO};
    pli.setLayoutCount = 1;
    pli.pSetLayouts = &setLayout;
    const VkPushConstantRange push{VK_SHADER_STAGE_COMPUTE_BIT, 0, sizeof(NearComputePush)};
    pli.pushConstantRangeCount = 1;
    pli.pPushConstantRanges = &push;
    VK_CHECK(vkCreatePipelineLayout(dev, &pli, nullptr, &pipelineLayout));

    const VkDescriptorPoolSize sizes[] = {{VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, 18},
                                          {VK_DESCRIPTOR_TYPE_COMBINED_IMAGE_SAMPLER, 1}};
    VkDescriptorPoolCreateInfo dpi{VK_STRUCTURE_TYPE_DESCRIPTOR_POOL_CREATE_INFO};
    dpi.maxSets = 1;
    dpi.poolSizeCount = std::uint32_t(std::size(sizes));
    dpi.pPoolSizes = sizes;
    VK_CHECK(vkCreateDescriptorPool(dev, &dpi, nullptr, &descriptorPool));
    VkDescriptorSetAllocateInfo dsa{VK_STRUCTURE_TYPE_DESCRIPTOR_SET_ALLOCATE_INFO};
    dsa.descriptorPool = descriptorPool;
    dsa.descriptorSetCount = 1;
    dsa.pSetLayouts = &setLayout;
    VK_CHECK(vkAllocateDescriptorSets(dev, &dsa, &descriptorSet));

    // Colour + id + depth, cleared on load, kept for the copy to host memory.
    VkAttachmentDescription att[3]{};
    for (int i = 0; i < 3; ++i) {
        att[i].format = i == 2 ? kDepthFormat : (i == 0 ? kColorFormat : kIdFormat);
        att[i].samples = VK_SAMPLE_COUNT_1_BIT;
        att[i].loadOp = VK_ATTACHMENT_LOAD_OP_CLEAR;
        att[i].storeOp = VK_ATTACHMENT_STORE_OP_STORE;
        att[i].stencilLoadOp = VK_ATTACHMENT_LOAD_OP_DONT_CARE;
        att[i].stencilStoreOp = VK_ATTACHMENT_STORE_OP_DONT_CARE;
        att[i].initialLayout = VK_IMAGE_LAYOUT_UNDEFINED;
        att[i].finalLayout = VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL;
    }
    const VkAttachmentReference colorRefs[2] = {{0, VK_IMAGE_LAYOUT_COLOR_ATTACHMENT_OPTIMAL},
                                                {1, VK_IMAGE_LAYOUT_COLOR_ATTACHMENT_OPTIMAL}};
    const VkAttachmentReference depthRef{2, VK_IMAGE_LAYOUT_DEPTH_STENCIL_ATTACHMENT_OPTIMAL};
    VkSubpassDescription sub{};
    sub.pipelineBindPoint = VK_PIPELINE_BIND_POINT_GRAPHICS;
    sub.colorAttachmentCount = 2;
    sub.pColorAttachments = colorRefs;
    sub.pDepthStencilAttachment = &depthRef;
    const VkPipelineStageFlags attachmentStages = VK_PIPELINE_STAGE_COLOR_ATTACHMENT_OUTPUT_BIT |
                                                  VK_PIPELINE_STAGE_EARLY_FRAGMENT_TESTS_BIT |
                                                  VK_PIPELINE_STAGE_LATE_FRAGMENT_TESTS_BIT;
    const VkAccessFlags attachmentAccess =
        VK_ACCESS_COLOR_ATTACHMENT_WRITE_BIT | VK_ACCESS_COLOR_ATTACHMENT_READ_BIT |
        VK_ACCESS_DEPTH_STENCIL_ATTACHMENT_WRITE_BIT | VK_ACCESS_DEPTH_STENCIL_ATTACHMENT_READ_BIT;
    const VkSubpassDependency deps[2] = {
        // The previous frame's copy-out must finish reading before the clear overwrites.
        {VK_SUBPASS_EXTERNAL, 0, VK_PIPELINE_STAGE_TRANSFER_BIT, attachmentStages, 0,
         attachmentAccess, 0},
        // The copy-out reads what the subpass wrote.
        {0, VK_SUBPASS_EXTERNAL, attachmentStages, VK_PIPELINE_STAGE_TRANSFER_BIT,
         VK_ACCESS_COLOR_ATTACHMENT_WRITE_BIT | VK_ACCESS_DEPTH_STENCIL_ATTACHMENT_WRITE_BIT,
         VK_ACCESS_TRANSFER_READ_BIT, 0},
    };
    VkRenderPassCreateInfo rpi{VK_STRUCTURE_TYPE_RENDER_PASS_CREATE_INFO};
    rpi.attachmentCount = 3;
    rpi.pAttachments = att;
    rpi.subpassCount = 1;
    rpi.pSubpasses = &sub;
    rpi.dependencyCount = 2;
    rpi.pDependencies = deps;
    VK_CHECK(vkCreateRenderPass(dev, &rpi, nullptr, &renderPass));

    if (device.hasPipelineStatistics()) {
        VkQueryPoolCreateInfo qpi{VK_STRUCTURE_TYPE_QUERY_POOL_CREATE_INFO};
        qpi.queryType = VK_QUERY_TYPE_PIPELINE_STATISTICS;
        qpi.queryCount = 1;
        qpi.pipelineStatistics = VK_QUERY_PIPELINE_STATISTIC_FRAGMENT_SHADER_INVOCATIONS_BIT;
        VK_CHECK(vkCreateQueryPool(dev, &qpi, nullptr, &statsPool));
    }

    if (device.properties().limits.timestampComputeAndGraphics) {
        VkQueryPoolCreateInfo qpi{VK_STRUCTURE_TYPE_QUERY_POOL_CREATE_INFO};
        qpi.queryType = VK_QUERY_TYPE_TIMESTAMP;
        qpi.queryCount = kTimestamps;
        VK_CHECK(vkCreateQueryPool(dev, &qpi, nullptr, &timePool));
    }

    drawCb = device.allocateCommandBuffer();
    counters =
        VulkanBuffer(device, sizeof(near_gpu::NearCounters),
                     VK_BUFFER_USAGE_STORAGE_BUFFER_BIT | VK_BUFFER_USAGE_TRANSFER_DST_BIT, true);
    ensureBuffer(sprites, sizeof(kernel::SpriteGpu) * 64, VK_BUFFER_USAGE_STORAGE_BUFFER_BIT);
    ensureBuffer(boxes, sizeof(near_gpu::NearBox) * 64, VK_BUFFER_USAGE_STORAGE_BUFFER_BIT);
    ensureBuffer(hulls, sizeof(near_gpu::NearHull) * 64, VK_BUFFER_USAGE_STORAGE_BUFFER_BIT);
    ensureBuffer(cellBases, 4096, VK_BUFFER_USAGE_STORAGE_BUFFER_BIT);
    ensureBuffer(cellTiles, 4096, VK_BUFFER_USAGE_STORAGE_BUFFER_BIT);
    ensureBuffer(splatBlocks, 4096, VK_BUFFER_USAGE_STORAGE_BUFFER_BIT);
    ensureBuffer(rankSprites, 4096, VK_BUFFER_USAGE_STORAGE_BUFFER_BIT);
    ensureBuffer(cells, 4096, VK_BUFFER_USAGE_STORAGE_BUFFER_BIT, false);
    ensureBuffer(farInstances, sizeof(far_gpu::FarInstanceGpu) * 64,
                 VK_BUFFER_USAGE_STORAGE_BUFFER_BIT);
    ensureBuffer(farPalettes, 4096, VK_BUFFER_USAGE_STORAGE_BUFFER_BIT);
    ensureBuffer(farTiles, 4096, VK_BUFFER_USAGE_STORAGE_BUFFER_BIT);
    ensureBuffer(farTileList, 4096, VK_BUFFER_USAGE_STORAGE_BUFFER_BIT);
}

void NearRenderer::Impl::destroy() noexcept {
    VkDevice dev = device.device();
    if (!dev) return;
    vkDeviceWaitIdle(dev);
    for (auto& perProxy : pipelines)
        for (auto& perCount : perProxy)
            for (VkPipeline& p : perCount) {
                if (p) vkDestroyPipeline(dev, p, nullptr);
                p = VK_NULL_HANDLE;
            }
    for (VkPipeline& p : computePipelines) {
        if (p) vkDestroyPipeline(dev, p, nullptr);
        p = VK_NULL_HANDLE;
    }
    if (framebuffer) vkDestroyFramebuffer(dev, framebuffer, nullptr);
    framebuffer = VK_NULL_HANDLE;
    color.reset();
    id.reset();
    depth.reset();
    readback.reset();
    pixelWords.reset();
    sprites.reset();
    boxes.reset();
    hulls.reset();
    counters.reset();
    cellBases.reset();
    cellTiles.reset();
    splatBlocks.reset();
    rankSprites.reset();
    cells.reset();
    farInstances.reset();
    farPalettes.reset();
    farTiles.reset();
    farTileList.reset();
    device.freeCommandBuffer(drawCb);
    drawCb = VK_NULL_HANDLE;
    if (statsPool) vkDestroyQueryPool(dev, statsPool, nullptr);
    if (timePool) vkDestroyQueryPool(dev, timePool, nullptr);
    timePool = VK_NULL_HANDLE;
    if (renderPass) vkDestroyRenderPass(dev, renderPass, nullptr);
    if (descriptorPool) vkDestroyDescriptorPool(dev, descriptorPool, nullptr); // frees the set
    if (pipelineLayout) vkDestroyPipelineLayout(dev, pipelineLayout, nullptr);
    if (setLayout) vkDestroyDescriptorSetLayout(dev, setLayout, nullptr);
    if (sampler) vkDestroySampler(dev, sampler, nullptr);
    statsPool = VK_NULL_HANDLE;
    renderPass = VK_NULL_HANDLE;
    descriptorPool = VK_NULL_HANDLE;
    pipelineLayout = VK_NULL_HANDLE;
    setLayout = VK_NULL_HANDLE;
    sampler = VK_NULL_HANDLE;
}

VkPipeline NearRenderer::Impl::pipeline(NearProxy proxy, bool countSteps, bool flatDepth) {
    VkPipeline& slot = pipelines[int(proxy)][countSteps][flatDepth];
    if (slot) return slot;
    VkDevice dev = device.device();
    auto makeModule = [&](const std::uint32_t* code, std::size_t bytes) {
        VkShaderModuleCreateInfo mi{VK_STRUCTURE_TYPE_SHADER_MODULE_CREATE_INFO};
        mi.codeSize = bytes;
        mi.pCode = code;
        VkShaderModule m = VK_NULL_HANDLE;
        VK_CHECK(vkCreateShaderModule(dev, &mi, nullptr, &m));
        return m;
    };
    VkShaderModule vert = proxy == NearProxy::Box ? makeModule(near_box_vert, sizeof(near_box_vert))
                          : proxy == NearProxy::Hull
                              ? makeModule(near_hull_vert, sizeof(near_hull_vert))
                              : makeModule(near_quad_vert, sizeof(near_quad_vert));
    VkShaderModule frag = VK_NULL_HANDLE;
    try {
        frag = flatDepth
                   ? (countSteps ? makeModule(near_flat_steps_frag, sizeof near_flat_steps_frag)
                                 : makeModule(near_flat_frag, sizeof near_flat_frag))
               : countSteps ? makeModule(near_steps_frag, sizeof(near_steps_frag))
                            : makeModule(near_frag, sizeof(near_frag));

        VkPipelineShaderStageCreateInfo stages[2]{};
        stages[0] = {VK_STRUCTURE_TYPE_PIPELINE_SHADER_STAGE_CREATE_INFO,
                     nullptr,
                     0,
                     VK_SHADER_STAGE_VERTEX_BIT,
                     vert,
                     "main",
                     nullptr};
        stages[1] = {VK_STRUCTURE_TYPE_PIPELINE_SHADER_STAGE_CREATE_INFO,
                     nullptr,
                     0,
                     VK_SHADER_STAGE_FRAGMENT_BIT,
                     frag,
                     "main",
                     nullptr};
        VkPipelineVertexInputStateCreateInfo vin{
            VK_STRUCTURE_TYPE_PIPELINE_VERTEX_INPUT_STATE_CREATE_INFO};
        VkPipelineInputAssemblyStateCreateInfo ia{
            VK_STRUCTURE_TYPE_PIPELINE_INPUT_ASSEMBLY_STATE_CREATE_INFO};
        ia.topology = proxy != NearProxy::Quad ? VK_PRIMITIVE_TOPOLOGY_TRIANGLE_LIST
                                               : VK_PRIMITIVE_TOPOLOGY_TRIANGLE_STRIP;
        VkPipelineViewportStateCreateInfo vp{VK_STRUCTURE_TYPE_PIPELINE_VIEWPORT_STATE_CREATE_INFO};
        vp.viewportCount = 1;
        vp.scissorCount = 1;
        VkPipelineRasterizationStateCreateInfo rs{
            VK_STRUCTURE_TYPE_PIPELINE_RASTERIZATION_STATE_CREATE_INFO};
        rs.polygonMode = VK_POLYGON_MODE_FILL;
        // The quad may face either way after projection; the box is drawn by its front faces
        // only, so each covered pixel runs the kernel once (see near_box.vert for the winding).
        rs.cullMode = proxy == NearProxy::Box ? VK_CULL_MODE_BACK_BIT : VK_CULL_MODE_NONE;
        rs.frontFace = VK_FRONT_FACE_COUNTER_CLOCKWISE;
        rs.lineWidth = 1.0f;
        VkPipelineMultisampleStateCreateInfo ms{
            VK_STRUCTURE_TYPE_PIPELINE_MULTISAMPLE_STATE_CREATE_INFO};
        ms.rasterizationSamples = VK_SAMPLE_COUNT_1_BIT;
        VkPipelineDepthStencilStateCreateInfo ds{
            VK_STRUCTURE_TYPE_PIPELINE_DEPTH_STENCIL_STATE_CREATE_INFO};
        // Reversed-Z: nearer is larger. GREATER (not GREATER_OR_EQUAL) keeps the first fragment
        // at equal depth, i.e. the lower entity id, because instances are in ascending id.
        ds.depthTestEnable = VK_TRUE;
        ds.depthWriteEnable = VK_TRUE;
        ds.depthCompareOp = VK_COMPARE_OP_GREATER;
        VkPipelineColorBlendAttachmentState blend[2]{};
        for (auto& b : blend)
            b.colorWriteMask = VK_COLOR_COMPONENT_R_BIT; // integer targets: no blending
        VkPipelineColorBlendStateCreateInfo cb{
            VK_STRUCTURE_TYPE_PIPELINE_COLOR_BLEND_STATE_CREATE_INFO};
        cb.attachmentCount = 2;
        cb.pAttachments = blend;
        const VkDynamicState dynamic[] = {VK_DYNAMIC_STATE_VIEWPORT, VK_DYNAMIC_STATE_SCISSOR};
        VkPipelineDynamicStateCreateInfo dyn{VK_STRUCTURE_TYPE_PIPELINE_DYNAMIC_STATE_CREATE_INFO};
        dyn.dynamicStateCount = 2;
        dyn.pDynamicStates = dynamic;

        VkGraphicsPipelineCreateInfo gpi{VK_STRUCTURE_TYPE_GRAPHICS_PIPELINE_CREATE_INFO};
        gpi.stageCount = 2;
        gpi.pStages = stages;
        gpi.pVertexInputState = &vin;
        gpi.pInputAssemblyState = &ia;
        gpi.pViewportState = &vp;
        gpi.pRasterizationState = &rs;
        gpi.pMultisampleState = &ms;
        gpi.pDepthStencilState = &ds;
        gpi.pColorBlendState = &cb;
        gpi.pDynamicState = &dyn;
        gpi.layout = pipelineLayout;
        gpi.renderPass = renderPass;
        gpi.subpass = 0;
        VK_CHECK(vkCreateGraphicsPipelines(dev, VK_NULL_HANDLE, 1, &gpi, nullptr, &slot));
    } catch (...) {
        vkDestroyShaderModule(dev, vert, nullptr);
        if (frag) vkDestroyShaderModule(dev, frag, nullptr);
        throw;
    }
    vkDestroyShaderModule(dev, vert, nullptr);
    vkDestroyShaderModule(dev, frag, nullptr);
    return slot;
}

void NearRenderer::Impl::ensureTargets(int w, int h) {
    if (w == width && h == height && framebuffer) return;
    VkDevice dev = device.device();
    if (framebuffer) vkDestroyFramebuffer(dev, framebuffer, nullptr);
    framebuffer = VK_NULL_HANDLE;
    const VkExtent3D extent{std::uint32_t(w), std::uint32_t(h), 1};
    const VkImageUsageFlags colorUsage =
        VK_IMAGE_USAGE_COLOR_ATTACHMENT_BIT | VK_IMAGE_USAGE_TRANSFER_SRC_BIT;
    color = VulkanImage(device, VK_IMAGE_TYPE_2D, kColorFormat, extent, colorUsage,
                        VK_IMAGE_ASPECT_COLOR_BIT);
    id = VulkanImage(device, VK_IMAGE_TYPE_2D, kIdFormat, extent, colorUsage,
                     VK_IMAGE_ASPECT_COLOR_BIT);
    depth =
        VulkanImage(device, VK_IMAGE_TYPE_2D, kDepthFormat, extent,
                    VK_IMAGE_USAGE_DEPTH_STENCIL_ATTACHMENT_BIT | VK_IMAGE_USAGE_TRANSFER_SRC_BIT,
                    VK_IMAGE_ASPECT_DEPTH_BIT);
    const VkImageView views[3] = {color.view(), id.view(), depth.view()};
    VkFramebufferCreateInfo fci{VK_STRUCTURE_TYPE_FRAMEBUFFER_CREATE_INFO};
    fci.renderPass = renderPass;
    fci.attachmentCount = 3;
    fci.pAttachments = views;
    fci.width = std::uint32_t(w);
    fci.height = std::uint32_t(h);
    fci.layers = 1;
    VK_CHECK(vkCreateFramebuffer(dev, &fci, nullptr, &framebuffer));
    const VkDeviceSize plane = VkDeviceSize(w) * VkDeviceSize(h) * 4;
    readback =
        VulkanBuffer(device, 3 * plane,
                     VK_BUFFER_USAGE_TRANSFER_DST_BIT | VK_BUFFER_USAGE_STORAGE_BUFFER_BIT, true);
    pixelWords =
        VulkanBuffer(device, plane,
                     VK_BUFFER_USAGE_TRANSFER_DST_BIT | VK_BUFFER_USAGE_STORAGE_BUFFER_BIT, false);
    width = w;
    height = h;
}

void NearRenderer::Impl::ensureBuffer(VulkanBuffer& b, VkDeviceSize bytes, VkBufferUsageFlags usage,
                                      bool hostVisible) {
    if (b && b.size() >= bytes) return;
    VkDeviceSize size = b ? b.size() : 4096;
    while (size < bytes) size *= 2;
    b = VulkanBuffer(device, size, usage, hostVisible);
}

VkPipeline NearRenderer::Impl::computePipeline(ComputePass pass) {
    VkPipeline& slot = computePipelines[pass];
    if (slot) return slot;
    VkDevice dev = device.device();
    VkShaderModuleCreateInfo mi{VK_STRUCTURE_TYPE_SHADER_MODULE_CREATE_INFO};
    const std::span<const std::uint32_t> code =
        pass == TraceCells ? std::span<const std::uint32_t>(near_cells_comp)
        : pass == Outline  ? std::span<const std::uint32_t>(near_cell_outline_comp)
        : pass == Splat    ? std::span<const std::uint32_t>(near_splat_comp)
        : pass == Resolve  ? std::span<const std::uint32_t>(near_resolve_comp)
                           : std::span<const std::uint32_t>(far_blit_comp);
    mi.codeSize = code.size_bytes();
    mi.pCode = code.data();
    VkShaderModule module = VK_NULL_HANDLE;
    VK_CHECK(vkCreateShaderModule(dev, &mi, nullptr, &module));
    VkComputePipelineCreateInfo cpi{VK_STRUCTURE_TYPE_COMPUTE_PIPELINE_CREATE_INFO};
    cpi.stage = {VK_STRUCTURE_TYPE_PIPELINE_SHADER_STAGE_CREATE_INFO,
                 nullptr,
                 0,
                 VK_SHADER_STAGE_COMPUTE_BIT,
                 module,
                 "main",
                 nullptr};
    cpi.layout = pipelineLayout;
    const VkResult r = vkCreateComputePipelines(dev, VK_NULL_HANDLE, 1, &cpi, nullptr, &slot);
    vkDestroyShaderModule(dev, module, nullptr);
    VK_CHECK(r);
    return slot;
}

NearRenderer::Impl::CellWork
NearRenderer::Impl::prepareCells(const CellRatePlan& plan,
                                 const std::vector<const SpriteSetup*>& visible,
                                 std::uint64_t budgetBytes) {
    using near_gpu::NEAR_SPLAT_BLOCK;
    const std::size_t n = visible.size();
    // Per-frame host-visible arrays: grown as needed, at least 4 bytes (a binding never has
    // size 0), and no memcpy from an empty vector's data() (null: undefined even for 0 bytes).
    const auto upload = [&](VulkanBuffer& b, const auto& v) {
        const std::size_t bytes = v.size() * sizeof(v[0]);
        ensureBuffer(b, std::max<std::size_t>(bytes, 4), VK_BUFFER_USAGE_STORAGE_BUFFER_BIT);
        if (bytes) std::memcpy(b.mapped(), v.data(), bytes);
    };
    upload(cellBases, plan.cellBase);
    // The store is kept for the next frames and grows by doubling, never past the budget (the
    // plan never needs more than the budget).
    const VkDeviceSize need = plan.cells * kCellStoreBytesPerCell;
    if (cells.size() < need)
        cells = VulkanBuffer(device,
                             std::max(need, std::min<VkDeviceSize>(2 * cells.size(), budgetBytes)),
                             VK_BUFFER_USAGE_STORAGE_BUFFER_BIT, false);
    std::vector<glm::uvec2> tiles;
    std::vector<near_gpu::NearSplatBlock> blocks;
    std::vector<std::uint32_t> byDepth; // cell-rate sprites, nearest first, ties by entity id
    byDepth.reserve(plan.cellSprites);
    // The resolve's tiles: every 32x32 tile of the image grid that a cell-rate rectangle touches,
    // once, so that a frame with a few small cell-rate sprites resolves a few tiles and not the
    // whole image.
    const int tilesX = (width + int(NEAR_SPLAT_BLOCK) - 1) / int(NEAR_SPLAT_BLOCK);
    const int tilesY = (height + int(NEAR_SPLAT_BLOCK) - 1) / int(NEAR_SPLAT_BLOCK);
    std::vector<std::uint8_t> touched(std::size_t(tilesX) * std::size_t(tilesY), 0);
    for (std::size_t k = 0; k < n; ++k) {
        if (plan.cellBase[k] == kNoCells) continue;
        byDepth.push_back(std::uint32_t(k));
        const std::uint64_t count = cellCount(*visible[k]);
        for (std::uint64_t first = 0; first < count; first += near_gpu::NEAR_CELL_TILE)
            tiles.push_back({std::uint32_t(k), std::uint32_t(first)});
        const glm::ivec4 r =
            glm::min(visible[k]->screenRect, glm::ivec4(width, height, width, height));
        const std::uint32_t end = std::uint32_t(r.z) | std::uint32_t(r.w) << 16;
        for (int y = r.y; y < r.w; y += int(NEAR_SPLAT_BLOCK))
            for (int x = r.x; x < r.z; x += int(NEAR_SPLAT_BLOCK))
                blocks.push_back(
                    {std::uint32_t(k), std::uint32_t(x) | std::uint32_t(y) << 16, end, 0});
        if (r.z <= r.x || r.w <= r.y) continue;
        for (int ty = r.y / int(NEAR_SPLAT_BLOCK); ty <= (r.w - 1) / int(NEAR_SPLAT_BLOCK); ++ty)
            for (int tx = r.x / int(NEAR_SPLAT_BLOCK); tx <= (r.z - 1) / int(NEAR_SPLAT_BLOCK);
                 ++tx)
                touched[std::size_t(ty) * std::size_t(tilesX) + std::size_t(tx)] = 1;
    }
    // `visible` is in ascending entity id, so a stable sort by depth alone gives
    // Image::writeIfNearer's order: the least rank in a pixel is the sprite the depth test keeps.
    std::stable_sort(byDepth.begin(), byDepth.end(), [&](std::uint32_t a, std::uint32_t b) {
        return visible[a]->gpu.depth > visible[b]->gpu.depth;
    });
    std::vector<std::uint32_t> ranks(n, near_gpu::NEAR_NO_RANK);
    for (std::size_t r = 0; r < byDepth.size(); ++r) ranks[byDepth[r]] = std::uint32_t(r);
    for (auto& b : blocks) b.rank = ranks[b.sprite];
    // The resolve tiles follow the splat blocks in the same buffer.
    const std::uint32_t splatCount = std::uint32_t(blocks.size());
    const std::uint32_t imageEnd = std::uint32_t(width) | std::uint32_t(height) << 16;
    for (int ty = 0; ty < tilesY; ++ty)
        for (int tx = 0; tx < tilesX; ++tx)
            if (touched[std::size_t(ty) * std::size_t(tilesX) + std::size_t(tx)])
                blocks.push_back({0,
                                  std::uint32_t(tx) * NEAR_SPLAT_BLOCK |
                                      (std::uint32_t(ty) * NEAR_SPLAT_BLOCK) << 16,
                                  imageEnd, 0});
    upload(cellTiles, tiles);
    upload(splatBlocks, blocks);
    upload(rankSprites, byDepth);
    return {std::uint32_t(tiles.size()), splatCount, std::uint32_t(blocks.size()) - splatCount};
}

void NearRenderer::Impl::dispatch(VkCommandBuffer cb, ComputePass pass, std::uint32_t groups,
                                  std::uint32_t first) {
    // A list of workgroups, as a 2D grid when there are more than one dimension allows.
    const std::uint32_t maxX = device.properties().limits.maxComputeWorkGroupCount[0];
    const std::uint32_t groupsX = std::min(groups, maxX);
    vkCmdBindPipeline(cb, VK_PIPELINE_BIND_POINT_COMPUTE, computePipeline(pass));
    vkCmdBindDescriptorSets(cb, VK_PIPELINE_BIND_POINT_COMPUTE, pipelineLayout, 0, 1,
                            &descriptorSet, 0, nullptr);
    const near_gpu::NearComputePush push{groups, std::uint32_t(width), std::uint32_t(height),
                                         frameCells, first};
    vkCmdPushConstants(cb, pipelineLayout, VK_SHADER_STAGE_COMPUTE_BIT, 0, sizeof push, &push);
    vkCmdDispatch(cb, groupsX, (groups + groupsX - 1) / groupsX, 1);
}

void NearRenderer::Impl::recordCellPasses(VkCommandBuffer cb, CellWork work) {
    const auto cellsWritten = [&] {
        bufferBarrier(cb, cells.handle(), VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT,
                      VK_ACCESS_SHADER_WRITE_BIT, VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT,
                      VK_ACCESS_SHADER_READ_BIT | VK_ACCESS_SHADER_WRITE_BIT);
    };
    dispatch(cb, TraceCells, work.tiles);
    cellsWritten(); // the outline pass reads the primaries
    dispatch(cb, Outline, work.tiles);
    vkCmdFillBuffer(cb, pixelWords.handle(), 0, VK_WHOLE_SIZE, near_gpu::NEAR_NO_RANK);
    // The splat reads the outcomes and min-writes the cleared words.
    cellsWritten();
    bufferBarrier(cb, pixelWords.handle(), VK_PIPELINE_STAGE_TRANSFER_BIT,
                  VK_ACCESS_TRANSFER_WRITE_BIT, VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT,
                  VK_ACCESS_SHADER_READ_BIT | VK_ACCESS_SHADER_WRITE_BIT);
    if (work.blocks) dispatch(cb, Splat, work.blocks);
}

void NearRenderer::Impl::recordResolve(VkCommandBuffer cb, CellWork work) {
    // After the copy of the drawn targets into the readback buffer (this command buffer) and the
    // splat (the frame's draw submission, earlier on the same queue).
    bufferBarrier(cb, readback.handle(), VK_PIPELINE_STAGE_TRANSFER_BIT,
                  VK_ACCESS_TRANSFER_WRITE_BIT, VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT,
                  VK_ACCESS_SHADER_READ_BIT | VK_ACCESS_SHADER_WRITE_BIT);
    bufferBarrier(cb, pixelWords.handle(), VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT,
                  VK_ACCESS_SHADER_WRITE_BIT, VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT,
                  VK_ACCESS_SHADER_READ_BIT);
    dispatch(cb, Resolve, work.resolveTiles, work.blocks);
    bufferBarrier(cb, readback.handle(), VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT,
                  VK_ACCESS_SHADER_WRITE_BIT, VK_PIPELINE_STAGE_HOST_BIT, VK_ACCESS_HOST_READ_BIT);
}

std::uint32_t NearRenderer::Impl::prepareFar(const FarBatch& batch, NearStats& stats) {
    using near_gpu::NEAR_SPLAT_BLOCK;
    FarResidencyStats rs;
    const std::vector<std::uint32_t> offsets = farResidency.update(batch, &rs);
    stats.farSnapshotsUploaded = rs.snapshotsUploaded;
    stats.farBytesUploaded = rs.bytesUploaded;
    // The frame's palettes, one copy per model palette.
    std::unordered_map<const Palette*, std::uint32_t> paletteBase;
    std::vector<std::uint32_t> palettes;
    std::vector<far_gpu::FarInstanceGpu> instances;
    instances.reserve(batch.instances.size());
    const int block = int(NEAR_SPLAT_BLOCK);
    const int tilesX = (width + block - 1) / block, tilesY = (height + block - 1) / block;
    std::vector<std::uint32_t> perTile(std::size_t(tilesX) * std::size_t(tilesY) + 1, 0);
    const auto tileSpan = [&](const glm::ivec4& r) {
        return glm::ivec4(r.x / block, r.y / block, (r.z - 1) / block, (r.w - 1) / block);
    };
    for (const FarInstance& f : batch.instances) {
        const SpriteSetup& s = *f.sprite;
        if (!s.visible()) continue;
        // The far blit's rectangle: the sprite's screen rectangle within the image.
        const glm::ivec4 r =
            glm::clamp(s.screenRect, glm::ivec4(0), glm::ivec4(width, height, width, height));
        if (r.z <= r.x || r.w <= r.y) continue;
        const auto [it, added] = paletteBase.emplace(f.palette, std::uint32_t(palettes.size()));
        if (added)
            for (const Rgba8 c : f.palette->colors) palettes.push_back(std::uint32_t(c));
        const FarSnapshotCells& snap = batch.snapshots.at(f.snapshot);
        far_gpu::FarInstanceGpu g{};
        g.sprite = s.gpu;
        g.u0 = f.u0, g.ui = f.ui, g.uj = f.uj, g.v0 = f.v0, g.vi = f.vi, g.vj = f.vj;
        g.rect = r;
        g.snap = {offsets[f.snapshot], std::uint32_t(snap.width()), std::uint32_t(snap.height()),
                  std::uint32_t(snap.cellRange.x)};
        g.extra = {snap.cellRange.z, int(it->second), 0, 0};
        instances.push_back(g);
        const glm::ivec4 t = tileSpan(r);
        for (int ty = t.y; ty <= t.w; ++ty)
            for (int tx = t.x; tx <= t.z; ++tx)
                ++perTile[std::size_t(ty) * std::size_t(tilesX) + std::size_t(tx)];
    }
    // Tiles with far sprites, and each one's sprites (in instance order; the rule makes the
    // order irrelevant).
    std::vector<far_gpu::FarTile> tiles;
    std::vector<std::uint32_t> start(perTile.size(), 0);
    std::uint32_t total = 0;
    for (std::size_t k = 0; k + 1 < perTile.size(); ++k) {
        start[k] = total;
        if (perTile[k] == 0) continue;
        const std::uint32_t tx = std::uint32_t(k % std::size_t(tilesX)),
                            ty = std::uint32_t(k / std::size_t(tilesX));
        tiles.push_back(
            {tx * NEAR_SPLAT_BLOCK | (ty * NEAR_SPLAT_BLOCK) << 16, total, perTile[k], 0});
        total += perTile[k];
    }
    std::vector<std::uint32_t> list(total);
    for (std::uint32_t i = 0; i < instances.size(); ++i) {
        const glm::ivec4 t = tileSpan(instances[i].rect);
        for (int ty = t.y; ty <= t.w; ++ty)
            for (int tx = t.x; tx <= t.z; ++tx)
                list[start[std::size_t(ty) * std::size_t(tilesX) + std::size_t(tx)]++] = i;
    }
    const auto upload = [&](VulkanBuffer& b, const auto& v) {
        const std::size_t bytes = v.size() * sizeof(v[0]);
        ensureBuffer(b, std::max<std::size_t>(bytes, 4), VK_BUFFER_USAGE_STORAGE_BUFFER_BIT);
        if (bytes) std::memcpy(b.mapped(), v.data(), bytes);
    };
    upload(farInstances, instances);
    upload(farPalettes, palettes);
    upload(farTiles, tiles);
    upload(farTileList, list);
    stats.farSprites = instances.size();
    stats.farTiles = tiles.size();
    return std::uint32_t(tiles.size());
}

void NearRenderer::Impl::writeDescriptors() {
    // Rewritten every frame: cheap, and the set is never in use here (every frame is waited for).
    using namespace near_gpu;
    const VkDescriptorBufferInfo spriteInfo{sprites.handle(), 0, VK_WHOLE_SIZE};
    const VkDescriptorBufferInfo paletteInfo{residency.paletteBuffer(), 0, VK_WHOLE_SIZE};
    const VkDescriptorBufferInfo counterInfo{counters.handle(), 0, VK_WHOLE_SIZE};
    const VkDescriptorBufferInfo boxInfo{boxes.handle(), 0, VK_WHOLE_SIZE};
    const VkDescriptorBufferInfo hullInfo{hulls.handle(), 0, VK_WHOLE_SIZE};
    const VkDescriptorImageInfo atlasInfo{sampler, residency.atlasView(),
                                          VK_IMAGE_LAYOUT_SHADER_READ_ONLY_OPTIMAL};
    const VkDescriptorBufferInfo cellBaseInfo{cellBases.handle(), 0, VK_WHOLE_SIZE};
    const VkDescriptorBufferInfo cellInfo{cells.handle(), 0, VK_WHOLE_SIZE};
    const VkDescriptorBufferInfo tileInfo{cellTiles.handle(), 0, VK_WHOLE_SIZE};
    const VkDescriptorBufferInfo blockInfo{splatBlocks.handle(), 0, VK_WHOLE_SIZE};
    const VkDescriptorBufferInfo rankInfo{rankSprites.handle(), 0, VK_WHOLE_SIZE};
    const VkDescriptorBufferInfo pixelWordInfo{pixelWords.handle(), 0, VK_WHOLE_SIZE};
    const VkDescriptorBufferInfo readbackInfo{readback.handle(), 0, VK_WHOLE_SIZE};
    const VkDescriptorBufferInfo farInstanceInfo{farInstances.handle(), 0, VK_WHOLE_SIZE};
    const VkDescriptorBufferInfo farSnapshotInfo{farResidency.buffer(), 0, VK_WHOLE_SIZE};
    const VkDescriptorBufferInfo farPaletteInfo{farPalettes.handle(), 0, VK_WHOLE_SIZE};
    const VkDescriptorBufferInfo farTileInfo{farTiles.handle(), 0, VK_WHOLE_SIZE};
    const VkDescriptorBufferInfo farTileListInfo{farTileList.handle(), 0, VK_WHOLE_SIZE};
    const VkDescriptorBufferInfo brickInfo{residency.brickBuffer(), 0, VK_WHOLE_SIZE};
    constexpr int kWrites = 19;
    VkWriteDescriptorSet w[kWrites]{};
    const std::uint32_t binding[kWrites] = {
        NEAR_BINDING_SPRITES,      NEAR_BINDING_ATLAS,         NEAR_BINDING_PALETTES,
        NEAR_BINDING_COUNTERS,     NEAR_BINDING_BOXES,         NEAR_BINDING_HULLS,
        NEAR_BINDING_CELL_BASES,   NEAR_BINDING_CELLS,         NEAR_BINDING_CELL_TILES,
        NEAR_BINDING_SPLAT_BLOCKS, NEAR_BINDING_RANK_SPRITES,  NEAR_BINDING_PIXEL_WORDS,
        NEAR_BINDING_READBACK,     NEAR_BINDING_FAR_INSTANCES, NEAR_BINDING_FAR_SNAPSHOTS,
        NEAR_BINDING_FAR_PALETTES, NEAR_BINDING_FAR_TILES,     NEAR_BINDING_FAR_TILE_LIST,
        NEAR_BINDING_BRICKS};
    const VkDescriptorBufferInfo* buffers[kWrites] = {
        &spriteInfo,     nullptr,        &paletteInfo,     &counterInfo,     &boxInfo,
        &hullInfo,       &cellBaseInfo,  &cellInfo,        &tileInfo,        &blockInfo,
        &rankInfo,       &pixelWordInfo, &readbackInfo,    &farInstanceInfo, &farSnapshotInfo,
        &farPaletteInfo, &farTileInfo,   &farTileListInfo, &brickInfo};
    for (int i = 0; i < kWrites; ++i) {
        w[i].sType = VK_STRUCTURE_TYPE_WRITE_DESCRIPTOR_SET;
        w[i].dstSet = descriptorSet;
        w[i].dstBinding = binding[i];
        w[i].descriptorCount = 1;
        w[i].descriptorType =
            i == 1 ? VK_DESCRIPTOR_TYPE_COMBINED_IMAGE_SAMPLER : VK_DESCRIPTOR_TYPE_STORAGE_BUFFER;
        w[i].pBufferInfo = buffers[i];
    }
    w[1].pImageInfo = &atlasInfo;
    vkUpdateDescriptorSets(device.device(), kWrites, w, 0, nullptr);
}

Image NearRenderer::Impl::render(const CameraFrame& cam,
                                 const std::vector<std::shared_ptr<VoxelModel>>& models,
                                 std::span<const SpriteSetup* const> all, Rgba8 background,
                                 const NearOptions& opt, NearStats* statsOut) {
    NearStats stats;
    if (opt.countSteps && !device.hasFragmentAtomics())
        throw VulkanError("near tier: counting DDA steps needs fragmentStoresAndAtomics, which " +
                          device.name() + " lacks");
    // §6: ascending entity id, so that depth GREATER resolves ties to the lower id. Culled: front
    // to back with equal depths in ascending id, which keeps every pixel the same (the depth
    // test alone decides unequal depths, whatever their order).
    std::vector<const SpriteSetup*> visible;
    visible.reserve(all.size());
    for (const std::uint32_t i : drawOrder(all, opt.earlyDepthTest)) visible.push_back(all[i]);
    if (!opt.earlyDepthTest)
        std::stable_sort(
            visible.begin(), visible.end(),
            [](const SpriteSetup* a, const SpriteSetup* b) { return a->entityId < b->entityId; });
    stats.sprites = visible.size();

    const ResidencyStats up = residency.update(models, visible);
    stats.bytesUploaded = up.bytesUploaded;
    stats.uploadRegions = up.regions;
    stats.atlasGrowths = up.atlasGrowths;
    stats.uploadMs = up.milliseconds;

    const auto tDraw = Clock::now();
    ensureTargets(cam.width, cam.height);
    const std::size_t n = visible.size();
    ensureBuffer(sprites, std::max<std::size_t>(n, 1) * sizeof(kernel::SpriteGpu),
                 VK_BUFFER_USAGE_STORAGE_BUFFER_BIT);
    auto* gpu = static_cast<kernel::SpriteGpu*>(sprites.mapped());
    for (std::size_t i = 0; i < n; ++i) {
        const SpriteSetup& s = *visible[i];
        gpu[i] = s.gpu;
        // The only fields the near tier adds to what core computed: where the voxels and their
        // brick occupancy are.
        const VoxelModel& model = *models.at(std::size_t(s.model));
        gpu[i].atlas = residency.entry(model, s.frame);
        gpu[i].brickBase = residency.brickBase(model, s.frame);
    }
    if (opt.proxy == NearProxy::Box) {
        ensureBuffer(boxes, std::max<std::size_t>(n, 1) * sizeof(near_gpu::NearBox),
                     VK_BUFFER_USAGE_STORAGE_BUFFER_BIT);
        auto* box = static_cast<near_gpu::NearBox*>(boxes.mapped());
        for (std::size_t i = 0; i < n; ++i) {
            const auto corners = proxyBoxClipCorners(cam, *visible[i]);
            for (int k = 0; k < 8; ++k) box[i].corner[k] = glm::vec4(corners[std::size_t(k)]);
        }
    }
    // Culled hull sprites are rasterised flat at their own depth where that clips nothing the
    // perspective proxy keeps: every corner in front of the eye and within the depth range.
    // Then the corners are divided through on the host (w = 1) and z is the sprite's depth, so
    // every fragment's depth is that float exactly (a triangle of equal z has zero depth slope).
    // The rest (sprites through the near plane) keep the perspective proxy and the shader's depth.
    std::vector<std::uint8_t> flat(n, 0);
    if (opt.proxy == NearProxy::Hull) {
        ensureBuffer(hulls, std::max<std::size_t>(n, 1) * sizeof(near_gpu::NearHull),
                     VK_BUFFER_USAGE_STORAGE_BUFFER_BIT);
        auto* hull = static_cast<near_gpu::NearHull*>(hulls.mapped());
        for (std::size_t i = 0; i < n; ++i) {
            const auto corners = proxyHullClipCorners(cam, *visible[i]);
            hull[i].count = std::uint32_t(corners.size());
            bool flatten = opt.earlyDepthTest;
            for (const glm::dvec4& c : corners)
                flatten = flatten && c.w > 0.0 && c.z >= 0.0 && c.z <= c.w;
            flat[i] = flatten;
            stats.earlyDepthSprites += flatten;
            for (std::size_t k = 0; k < corners.size(); ++k)
                hull[i].corner[k] = flatten ? glm::vec4(float(corners[k].x / corners[k].w),
                                                        float(corners[k].y / corners[k].w),
                                                        visible[i]->gpu.depth, 1.0f)
                                            : glm::vec4(corners[k]);
        }
    }
    // The resolve pass binds the whole readback buffer; past the device's storage-buffer range
    // (a huge image) every sprite is traced per pixel.
    const bool resolvable = readback.size() <= device.properties().limits.maxStorageBufferRange;
    const CellRatePlan plan =
        planCellRate(visible, resolvable ? opt.rate : NearRate::Fragment, opt.cellBudgetBytes);
    stats.cellsTraced = plan.cells;
    stats.cellSprites = plan.cellSprites;
    stats.cellOverBudget = plan.overBudget;
    stats.pixelsTraced = plan.pixelsTraced;
    stats.pixelsLookedUp = plan.pixelsLookedUp;
    const CellWork work = prepareCells(plan, visible, opt.cellBudgetBytes);
    frameCells = std::uint32_t(plan.cells);
    // The far pass composes in the readback buffer like the resolve pass.
    const bool withFar = opt.far && !opt.far->empty();
    if (withFar && !device.hasFloat64())
        throw VulkanError("far pass: " + device.name() +
                          " lacks shaderFloat64, which the far pass needs (--far-backend cpu)");
    if (withFar && !resolvable)
        throw VulkanError("far pass: the image is larger than the device's storage buffer range");
    const auto tFar = Clock::now();
    const std::uint32_t farTileCount = withFar ? prepareFar(*opt.far, stats) : 0;
    const double farHostMs = withFar ? msSince(tFar) : 0.0;
    writeDescriptors();
    const bool query = opt.pipelineStatistics && statsPool && n;

    VkCommandBuffer cb = drawCb;
    VK_CHECK(vkResetCommandBuffer(cb, 0));
    VkCommandBufferBeginInfo bi{VK_STRUCTURE_TYPE_COMMAND_BUFFER_BEGIN_INFO};
    bi.flags = VK_COMMAND_BUFFER_USAGE_ONE_TIME_SUBMIT_BIT;
    VK_CHECK(vkBeginCommandBuffer(cb, &bi));
    if (query) vkCmdResetQueryPool(cb, statsPool, 0, 1);
    const bool clocked = timePool != VK_NULL_HANDLE;
    if (clocked) {
        vkCmdResetQueryPool(cb, timePool, 0, kTimestamps);
        vkCmdWriteTimestamp(cb, VK_PIPELINE_STAGE_TOP_OF_PIPE_BIT, timePool, 0);
    }
    // Cell-rate sprites: every cell traced once, then every pixel of theirs splatted; the draw
    // below skips them, the resolve pass after it shades them.
    if (work.tiles) recordCellPasses(cb, work);
    if (clocked) vkCmdWriteTimestamp(cb, VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT, timePool, 1);
    if (opt.countSteps) {
        vkCmdFillBuffer(cb, counters.handle(), 0, VK_WHOLE_SIZE, 0);
        bufferBarrier(cb, counters.handle(), VK_PIPELINE_STAGE_TRANSFER_BIT,
                      VK_ACCESS_TRANSFER_WRITE_BIT, VK_PIPELINE_STAGE_FRAGMENT_SHADER_BIT,
                      VK_ACCESS_SHADER_READ_BIT | VK_ACCESS_SHADER_WRITE_BIT);
    }
    VkClearValue clears[3]{};
    clears[0].color.uint32[0] = opt.clearColor.value_or(background);
    clears[1].color.uint32[0] = kernel::VT_NO_ENTITY;
    clears[2].depthStencil = {0.0f, 0}; // reversed-Z: 0 = infinitely far, nothing drawn
    VkRenderPassBeginInfo rbi{VK_STRUCTURE_TYPE_RENDER_PASS_BEGIN_INFO};
    rbi.renderPass = renderPass;
    rbi.framebuffer = framebuffer;
    rbi.renderArea = {{0, 0}, {std::uint32_t(width), std::uint32_t(height)}};
    rbi.clearValueCount = 3;
    rbi.pClearValues = clears;
    vkCmdBeginRenderPass(cb, &rbi, VK_SUBPASS_CONTENTS_INLINE);
    if (n) {
        vkCmdBindDescriptorSets(cb, VK_PIPELINE_BIND_POINT_GRAPHICS, pipelineLayout, 0, 1,
                                &descriptorSet, 0, nullptr);
        const VkViewport viewport{0.0f, 0.0f, float(width), float(height), 0.0f, 1.0f};
        const VkRect2D scissor{{0, 0}, {std::uint32_t(width), std::uint32_t(height)}};
        vkCmdSetViewport(cb, 0, 1, &viewport);
        vkCmdSetScissor(cb, 0, 1, &scissor);
        if (query) vkCmdBeginQuery(cb, statsPool, 0, 0);
        const std::uint32_t vertices = opt.proxy == NearProxy::Box ? near_gpu::NEAR_BOX_VERTICES
                                       : opt.proxy == NearProxy::Hull
                                           ? near_gpu::NEAR_HULL_VERTICES
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
        if (query) vkCmdEndQuery(cb, statsPool, 0);
    }
    vkCmdEndRenderPass(cb);
    if (opt.countSteps) {
        bufferBarrier(cb, counters.handle(), VK_PIPELINE_STAGE_FRAGMENT_SHADER_BIT,
                      VK_ACCESS_SHADER_WRITE_BIT, VK_PIPELINE_STAGE_HOST_BIT,
                      VK_ACCESS_HOST_READ_BIT);
    }

    // Read back, in the same command buffer (one submission a frame): the targets into one
    // host buffer (colour, id, depth), where the resolve and far passes compose, then unpack.
    // Colour alone where nobody asked for depth and ids and no pass composes on them.
    const VkDeviceSize plane = VkDeviceSize(width) * VkDeviceSize(height) * 4;
    const bool allPlanes = opt.readDepthAndIds || work.blocks || farTileCount;
    if (clocked) vkCmdWriteTimestamp(cb, VK_PIPELINE_STAGE_BOTTOM_OF_PIPE_BIT, timePool, 6);
    const VulkanImage* planes[3] = {&color, &id, &depth};
    for (int i = 0; i < (allPlanes ? 3 : 1); ++i) {
        VkBufferImageCopy region{};
        region.bufferOffset = plane * VkDeviceSize(i);
        region.imageSubresource = {planes[i]->aspect(), 0, 0, 1};
        region.imageExtent = {std::uint32_t(width), std::uint32_t(height), 1};
        vkCmdCopyImageToBuffer(cb, planes[i]->handle(), VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL,
                               readback.handle(), 1, &region);
    }
    if (clocked) vkCmdWriteTimestamp(cb, VK_PIPELINE_STAGE_TRANSFER_BIT, timePool, 7);
    if (work.blocks) {
        if (clocked) vkCmdWriteTimestamp(cb, VK_PIPELINE_STAGE_TRANSFER_BIT, timePool, 2);
        recordResolve(cb, work);
        if (clocked) vkCmdWriteTimestamp(cb, VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT, timePool, 3);
    }
    if (farTileCount) {
        // Far sprites: their new snapshots uploaded, then drawn over what the near tier left.
        if (clocked) vkCmdWriteTimestamp(cb, VK_PIPELINE_STAGE_BOTTOM_OF_PIPE_BIT, timePool, 4);
        farResidency.recordUploads(cb);
        bufferBarrier(cb, readback.handle(),
                      VK_PIPELINE_STAGE_TRANSFER_BIT | VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT,
                      VK_ACCESS_TRANSFER_WRITE_BIT | VK_ACCESS_SHADER_WRITE_BIT,
                      VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT,
                      VK_ACCESS_SHADER_READ_BIT | VK_ACCESS_SHADER_WRITE_BIT);
        dispatch(cb, FarBlit, farTileCount);
        if (clocked) vkCmdWriteTimestamp(cb, VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT, timePool, 5);
        bufferBarrier(cb, readback.handle(), VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT,
                      VK_ACCESS_SHADER_WRITE_BIT, VK_PIPELINE_STAGE_HOST_BIT,
                      VK_ACCESS_HOST_READ_BIT);
    } else if (!work.blocks) {
        bufferBarrier(cb, readback.handle(), VK_PIPELINE_STAGE_TRANSFER_BIT,
                      VK_ACCESS_TRANSFER_WRITE_BIT, VK_PIPELINE_STAGE_HOST_BIT,
                      VK_ACCESS_HOST_READ_BIT);
    }
    VK_CHECK(vkEndCommandBuffer(cb));
    device.submitAndWait(cb);
    const double frameMs = std::max(0.0, msSince(tDraw) - farHostMs);
    if (farTileCount) farResidency.uploadsDone();

    // The submission's time split by its timestamps (without them, all of it is draw time).
    const double tickMs = double(device.properties().limits.timestampPeriod) * 1e-6;
    const auto gpuMs = [&](std::uint32_t from) {
        std::uint64_t t[2] = {};
        VK_CHECK(vkGetQueryPoolResults(device.device(), timePool, from, 2, sizeof t, t, sizeof t[0],
                                       VK_QUERY_RESULT_64_BIT | VK_QUERY_RESULT_WAIT_BIT));
        return t[1] > t[0] ? double(t[1] - t[0]) * tickMs : 0.0;
    };
    double copyMs = 0.0, farGpuMs = 0.0;
    if (clocked) {
        stats.computeMs = gpuMs(0) + (work.blocks ? gpuMs(2) : 0.0);
        copyMs = gpuMs(6);
        if (farTileCount) farGpuMs = gpuMs(4);
    }
    stats.drawMs = std::max(0.0, frameMs - stats.computeMs - copyMs - farGpuMs);
    stats.farMs = farHostMs + farGpuMs;
    const auto tRead = Clock::now();
    Image img;
    img.width = width;
    img.height = height;
    const std::size_t count = img.pixelCount();
    // assign() copies straight in; resize() + memcpy would write every byte twice.
    const auto* base = static_cast<const std::uint8_t*>(readback.mapped());
    const auto* colors = reinterpret_cast<const Rgba8*>(base);
    const auto* ids = reinterpret_cast<const std::uint32_t*>(base + plane);
    const auto* depths = reinterpret_cast<const float*>(base + 2 * plane);
    img.color.assign(colors, colors + count);
    if (opt.readDepthAndIds) {
        img.id.assign(ids, ids + count);
        img.depth.assign(depths, depths + count);
    }
    stats.readbackMs = copyMs + msSince(tRead);

    if (query) {
        std::uint64_t invocations = 0;
        VK_CHECK(vkGetQueryPoolResults(device.device(), statsPool, 0, 1, sizeof invocations,
                                       &invocations, sizeof invocations,
                                       VK_QUERY_RESULT_64_BIT | VK_QUERY_RESULT_WAIT_BIT));
        stats.fragmentInvocations = invocations;
    }
    if (opt.countSteps) {
        const auto* c = static_cast<const near_gpu::NearCounters*>(counters.mapped());
        stats.voxelFetches = (std::uint64_t(c->fetchesHi) << 32) | c->fetchesLo;
        stats.kernelFragments = (std::uint64_t(c->fragmentsHi) << 32) | c->fragmentsLo;
    }
    if (statsOut) *statsOut = stats;
    return img;
}

NearRenderer::NearRenderer(const VulkanDeviceOptions& options,
                           std::shared_ptr<VulkanMessageLog> log)
    : impl_(std::make_unique<Impl>(options, std::move(log))) {}

NearRenderer::~NearRenderer() = default;

const std::string& NearRenderer::deviceName() const {
    return impl_->device.name();
}
bool NearRenderer::deviceIsCpu() const {
    return impl_->device.isCpu();
}
bool NearRenderer::farPassSupported() const {
    return impl_->device.hasFloat64();
}
std::uint64_t NearRenderer::farResidentBytes() const {
    return impl_->farResidency.residentBytes();
}
std::size_t NearRenderer::farResidentSnapshots() const {
    return impl_->farResidency.residentSnapshots();
}
bool NearRenderer::validationEnabled() const {
    return impl_->device.validationEnabled();
}
const std::shared_ptr<VulkanMessageLog>& NearRenderer::messageLog() const {
    return impl_->device.messageLog();
}
std::uint64_t NearRenderer::totalBytesUploaded() const {
    return impl_->residency.totals().bytesUploaded;
}

Image NearRenderer::render(const CameraFrame& camera,
                           const std::vector<std::shared_ptr<VoxelModel>>& models,
                           std::span<const SpriteSetup* const> sprites, Rgba8 background,
                           const NearOptions& options, NearStats* stats) {
    return impl_->render(camera, models, sprites, background, options, stats);
}

Image NearRenderer::render(const CameraFrame& camera,
                           const std::vector<std::shared_ptr<VoxelModel>>& models,
                           const std::vector<SpriteSetup>& sprites, Rgba8 background,
                           const NearOptions& options, NearStats* stats) {
    std::vector<const SpriteSetup*> ptrs;
    ptrs.reserve(sprites.size());
    for (const auto& s : sprites) ptrs.push_back(&s);
    return impl_->render(camera, models, ptrs, background, options, stats);
}

} // namespace voxtier
