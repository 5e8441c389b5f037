#include "volumetric/near_pipelines.hpp"

#include "volumetric/shaders/near_shared.h"

#include <algorithm>
#include <cstdint>
#include <cstdlib>
#include <span>
#include <string>

// SPIR-V generated at build time by glslangValidator (volumetric/CMakeLists.txt).
#include "shaders/near_box_vert.h"
#include "shaders/near_cell_outline_comp.h"
#include "shaders/near_cells_comp.h"
#include "shaders/near_cells_skip_comp.h"
#include "shaders/near_flat_frag.h"
#include "shaders/near_flat_steps_frag.h"
#include "shaders/near_frag.h"
#include "shaders/near_hull_vert.h"
#include "shaders/near_quad_vert.h"
#include "shaders/near_resolve_comp.h"
#include "shaders/near_skip_flat_frag.h"
#include "shaders/near_skip_flat_steps_frag.h"
#include "shaders/near_skip_frag.h"
#include "shaders/near_skip_steps_frag.h"
#include "shaders/near_splat_comp.h"
#include "shaders/near_steps_frag.h"
#include "shaders/near_trace_comp.h"
#include "shaders/near_trace_skip_comp.h"
#include "shaders/near_trace_skip_steps_comp.h"
#include "shaders/near_trace_steps_comp.h"

namespace voxtier {

VkPipeline createNearDrawPipeline(VkDevice dev, VkPipelineLayout layout, VkRenderPass renderPass,
                                  NearProxy proxy, bool countSteps, bool flatDepth,
                                  bool skipEmpty) {
    VkPipeline pipeline = VK_NULL_HANDLE;
    const std::span<const std::uint32_t> vertCode =
        proxy == NearProxy::Box    ? std::span<const std::uint32_t>(near_box_vert)
        : proxy == NearProxy::Hull ? std::span<const std::uint32_t>(near_hull_vert)
                                   : std::span<const std::uint32_t>(near_quad_vert);
    using Code = std::span<const std::uint32_t>;
    // [skipEmpty][flatDepth][countSteps]
    const Code variants[2][2][2] = {{{Code(near_frag), Code(near_steps_frag)},
                                     {Code(near_flat_frag), Code(near_flat_steps_frag)}},
                                    {{Code(near_skip_frag), Code(near_skip_steps_frag)},
                                     {Code(near_skip_flat_frag), Code(near_skip_flat_steps_frag)}}};
    const Code fragCode = variants[skipEmpty][flatDepth][countSteps];
    VkShaderModule vert = createShaderModule(dev, vertCode);
    VkShaderModule frag = VK_NULL_HANDLE;
    try {
        frag = createShaderModule(dev, fragCode);
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
        // at equal depth, i.e. the lower entity id, because equal depths are drawn in ascending id.
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
        gpi.layout = layout;
        gpi.renderPass = renderPass;
        gpi.subpass = 0;
        VK_CHECK(vkCreateGraphicsPipelines(dev, VK_NULL_HANDLE, 1, &gpi, nullptr, &pipeline));
    } catch (...) {
        vkDestroyShaderModule(dev, vert, nullptr);
        if (frag) vkDestroyShaderModule(dev, frag, nullptr);
        throw;
    }
    vkDestroyShaderModule(dev, vert, nullptr);
    vkDestroyShaderModule(dev, frag, nullptr);
    return pipeline;
}

VkPipeline createNearComputePipeline(VkDevice dev, VkPipelineLayout layout, NearComputePass pass,
                                     bool skipEmpty, bool countSteps, NearTraceShape traceShape) {
    using enum NearComputePass;
    using Code = std::span<const std::uint32_t>;
    // [skipEmpty][countSteps]
    const Code trace[2][2] = {{Code(near_trace_comp), Code(near_trace_steps_comp)},
                              {Code(near_trace_skip_comp), Code(near_trace_skip_steps_comp)}};
    const Code code = pass == TraceCells
                          ? (skipEmpty ? Code(near_cells_skip_comp) : Code(near_cells_comp))
                      : pass == Outline     ? Code(near_cell_outline_comp)
                      : pass == Splat       ? Code(near_splat_comp)
                      : pass == TracePixels ? trace[skipEmpty][countSteps]
                                            : Code(near_resolve_comp);
    const std::uint32_t shape[] = {traceShape.rows, traceShape.side}; // constant_id 0, 1
    return createComputePipeline(dev, layout, code,
                                 pass == TracePixels ? std::span<const std::uint32_t>(shape)
                                                     : std::span<const std::uint32_t>());
}

namespace {
/// The environment's power of two in [1, most] named `name`, or `fallback` where it is unset.
std::uint32_t powerOfTwoFromEnv(const char* name, std::uint32_t least, std::uint32_t most,
                                std::uint32_t fallback) {
    const char* v = std::getenv(name);
    if (!v) return fallback;
    for (std::uint32_t p = least; p <= most; p *= 2)
        if (std::string(v) == std::to_string(p)) return p;
    throw VulkanError(std::string(name) + ": expected a power of two from " +
                      std::to_string(least) + " to " + std::to_string(most) + ", got '" + v + "'");
}
} // namespace

NearTraceShape nearTraceShape(const VulkanDevice& device, std::size_t sprites) {
    NearTraceShape s =
        device.isCpu() || sprites > kFewTraceSprites ? NearTraceShape{32, 2} : NearTraceShape{8, 8};
    s.side = powerOfTwoFromEnv("VOXTIER_NEAR_TRACE_BLOCK", 8, 32, s.side);
    s.rows = std::min(s.side, powerOfTwoFromEnv("VOXTIER_NEAR_TRACE_ROWS", 1, 32, s.rows));
    return s;
}

} // namespace voxtier
