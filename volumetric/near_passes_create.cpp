// NearPasses' Vulkan objects: the layouts, the render pass, the per-slot buffers and the
// pipelines (created on first use), and their destruction.
#include "volumetric/detail/near_passes_impl.hpp"

namespace voxtier {

void NearPasses::Impl::create() {
    createLayouts();
    createRenderPass();
    slots.resize(std::size_t(frames.slots()));
    for (Slot& s : slots) createSlot(s);
}

void NearPasses::Impl::createLayouts() {
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
    const VkShaderStageFlags f = VK_SHADER_STAGE_FRAGMENT_BIT;
    const VkShaderStageFlags v = VK_SHADER_STAGE_VERTEX_BIT;
    const VkDescriptorType sb = VK_DESCRIPTOR_TYPE_STORAGE_BUFFER;
    const VkDescriptorSetLayoutBinding bindings[] = {
        {NEAR_BINDING_SPRITES, sb, 1, v | f | c, nullptr},
        {NEAR_BINDING_ATLAS, VK_DESCRIPTOR_TYPE_COMBINED_IMAGE_SAMPLER, 1, f | c, nullptr},
        {NEAR_BINDING_PALETTES, sb, 1, f | c, nullptr},
        {NEAR_BINDING_COUNTERS, sb, 1, f | c, nullptr},
        {NEAR_BINDING_BOXES, sb, 1, v, nullptr},
        {NEAR_BINDING_HULLS, sb, 1, v, nullptr},
        {NEAR_BINDING_CELL_BASES, sb, 1, v | c, nullptr},
        {NEAR_BINDING_CELLS, sb, 1, c, nullptr},
        {NEAR_BINDING_CELL_TILES, sb, 1, c, nullptr},
        {NEAR_BINDING_SPLAT_BLOCKS, sb, 1, c, nullptr},
        {NEAR_BINDING_RANK_SPRITES, sb, 1, c, nullptr},
        {NEAR_BINDING_PIXEL_WORDS, sb, 1, c, nullptr},
        {NEAR_BINDING_PLANES, sb, 1, c, nullptr},
        {NEAR_BINDING_BRICKS, sb, 1, f | c, nullptr},
        {NEAR_BINDING_RECORD_OF, sb, 1, f | c, nullptr},
    };
    // The draw's pipelines share the layout; its push constants are the compute passes' alone.
    createPassLayouts(dev, bindings, sizeof(NearComputePush), setLayout, pipelineLayout);

    const std::uint32_t n = std::uint32_t(frames.slots());
    // Every binding but the atlas is a storage buffer.
    const std::uint32_t buffersPerSet = std::uint32_t(std::size(bindings)) - 1;
    const VkDescriptorPoolSize sizes[] = {{sb, buffersPerSet * n},
                                          {VK_DESCRIPTOR_TYPE_COMBINED_IMAGE_SAMPLER, n}};
    VkDescriptorPoolCreateInfo dpi{VK_STRUCTURE_TYPE_DESCRIPTOR_POOL_CREATE_INFO};
    dpi.maxSets = n;
    dpi.poolSizeCount = std::uint32_t(std::size(sizes));
    dpi.pPoolSizes = sizes;
    VK_CHECK(vkCreateDescriptorPool(dev, &dpi, nullptr, &descriptorPool));
}

void NearPasses::Impl::createRenderPass() {
    // Colour + id + depth, cleared on load, kept for the copy into the frame's planes.
    VkAttachmentDescription att[3]{};
    for (int i = 0; i < 3; ++i) {
        att[i].format = i == 2 ? GpuFrame::kDepthFormat
                               : (i == 0 ? GpuFrame::kColorFormat : GpuFrame::kIdFormat);
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
    VK_CHECK(vkCreateRenderPass(device.device(), &rpi, nullptr, &renderPass));
}

void NearPasses::Impl::createSlot(Slot& s) {
    VkDevice dev = device.device();
    VkDescriptorSetAllocateInfo dsa{VK_STRUCTURE_TYPE_DESCRIPTOR_SET_ALLOCATE_INFO};
    dsa.descriptorPool = descriptorPool;
    dsa.descriptorSetCount = 1;
    dsa.pSetLayouts = &setLayout;
    VK_CHECK(vkAllocateDescriptorSets(dev, &dsa, &s.set));
    if (device.hasPipelineStatistics()) {
        VkQueryPoolCreateInfo qpi{VK_STRUCTURE_TYPE_QUERY_POOL_CREATE_INFO};
        qpi.queryType = VK_QUERY_TYPE_PIPELINE_STATISTICS;
        qpi.queryCount = 1;
        qpi.pipelineStatistics = VK_QUERY_PIPELINE_STATISTIC_FRAGMENT_SHADER_INVOCATIONS_BIT;
        VK_CHECK(vkCreateQueryPool(dev, &qpi, nullptr, &s.statsPool));
    }
    s.counters = VulkanBuffer(device, sizeof(near_gpu::NearCounters),
                              VK_BUFFER_USAGE_STORAGE_BUFFER_BIT, BufferClass::Readback);
    // Every binding has a buffer from the start (a binding never has size 0).
    for (VulkanBuffer* b : {&s.sprites, &s.boxes, &s.hulls, &s.cellBases, &s.cellTiles,
                            &s.splatBlocks, &s.rankSprites, &s.recordOf})
        ensure(*b, 4096);
}

void NearPasses::Impl::destroy() noexcept {
    VkDevice dev = device.device();
    if (!dev) return;
    frames.waitAll();
    for (auto& perProxy : pipelines)
        for (auto& perCount : perProxy)
            for (auto& perFlat : perCount)
                for (VkPipeline& p : perFlat) {
                    if (p) vkDestroyPipeline(dev, p, nullptr);
                    p = VK_NULL_HANDLE;
                }
    for (auto& perPass : computePipelines)
        for (VkPipeline& p : perPass) {
            if (p) vkDestroyPipeline(dev, p, nullptr);
            p = VK_NULL_HANDLE;
        }
    for (auto& [shape, four] : tracePipelines)
        for (VkPipeline p : four)
            if (p) vkDestroyPipeline(dev, p, nullptr);
    tracePipelines.clear();
    for (Slot& s : slots)
        if (s.statsPool) vkDestroyQueryPool(dev, s.statsPool, nullptr);
    slots.clear();
    cells.reset();
    pixelWords.reset();
    if (framebuffer) vkDestroyFramebuffer(dev, framebuffer, nullptr);
    if (renderPass) vkDestroyRenderPass(dev, renderPass, nullptr);
    if (descriptorPool) vkDestroyDescriptorPool(dev, descriptorPool, nullptr); // frees the sets
    if (pipelineLayout) vkDestroyPipelineLayout(dev, pipelineLayout, nullptr);
    if (setLayout) vkDestroyDescriptorSetLayout(dev, setLayout, nullptr);
    if (sampler) vkDestroySampler(dev, sampler, nullptr);
    framebuffer = VK_NULL_HANDLE;
    renderPass = VK_NULL_HANDLE;
    descriptorPool = VK_NULL_HANDLE;
    pipelineLayout = VK_NULL_HANDLE;
    setLayout = VK_NULL_HANDLE;
    sampler = VK_NULL_HANDLE;
}

void NearPasses::Impl::ensure(VulkanBuffer& b, VkDeviceSize bytes, BufferClass c) {
    if (b && b.size() >= bytes) return;
    VkDeviceSize size = b ? b.size() : 4096;
    while (size < bytes) size *= 2;
    b = VulkanBuffer(device, size, VK_BUFFER_USAGE_STORAGE_BUFFER_BIT, c);
}

VkPipeline NearPasses::Impl::pipeline(NearProxy proxy, bool countSteps, bool flatDepth) {
    VkPipeline& slot = pipelines[int(proxy)][countSteps][flatDepth][skipEmpty];
    if (!slot)
        slot = createNearDrawPipeline(device.device(), pipelineLayout, renderPass, proxy,
                                      countSteps, flatDepth, skipEmpty);
    return slot;
}

VkPipeline NearPasses::Impl::computePipeline(ComputePass pass) {
    static_assert(int(TracePixels) == int(NearComputePass::TracePixels) &&
                  int(Resolve) == int(NearComputePass::Resolve));
    const bool skip = (pass == TraceCells || pass == TracePixels) && skipEmpty;
    const bool count = pass == TracePixels && countSteps;
    VkPipeline& slot =
        pass == TracePixels
            ? tracePipelines[{traceShape.side, traceShape.rows}][std::size_t(skip) * 2 + count]
            : computePipelines[pass][skip];
    if (!slot)
        slot =
            createNearComputePipeline(device.device(), pipelineLayout,
                                      static_cast<NearComputePass>(pass), skip, count, traceShape);
    return slot;
}

} // namespace voxtier
