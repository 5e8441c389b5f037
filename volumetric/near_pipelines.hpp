#pragma once
// The near tier's pipelines: the draw's graphics pipeline per proxy and shader variant, and the
// cell-rate compute passes' pipelines, built from the SPIR-V compiled at build time. NearPasses
// caches them (created on first use); this file only builds them.
#include "device/vulkan_device.hpp"
#include "volumetric/near_proxy.hpp"

#include <vulkan/vulkan.h>

#include <cstddef>
#include <cstdint>

namespace voxtier {

/// The draw's pipeline: `proxy`'s vertex shader and near.frag, its variant counting voxel reads
/// (`countSteps`), writing no depth for a flattened proxy (`flatDepth`), holding the box march
/// (`skipEmpty`, the variant compiled with VT_SKIP_EMPTY). Reversed-Z depth test GREATER, two
/// integer targets.
VkPipeline createNearDrawPipeline(VkDevice dev, VkPipelineLayout layout, VkRenderPass renderPass,
                                  NearProxy proxy, bool countSteps, bool flatDepth, bool skipEmpty);

/// The compute passes, in the order a frame records them: the cell-rate sprites' cells, their
/// outline and splat, the per-pixel sprites' trace (NearPixels::Compute), the resolve.
enum class NearComputePass { TraceCells, Outline, Splat, TracePixels, Resolve };
/// The trace's workgroup: square blocks of `side` pixels of a sprite's rectangle, `rows` of them
/// run at once (rows <= side).
struct NearTraceShape {
    std::uint32_t side = 32, rows = 2;
};
/// Per-pixel sprites up to which a GPU frame traces in 8x8 blocks (see nearTraceShape).
inline constexpr std::size_t kFewTraceSprites = 8192;
/// On `device`, for a frame that traces `sprites` per-pixel sprites: 32-pixel blocks two rows at
/// a time on a CPU device (llvmpipe pays per workgroup invocation); on a GPU 8x8 blocks a pixel
/// each up to kFewTraceSprites sprites, and past them 32-pixel blocks two rows at a time, as on a
/// CPU (the measurements behind it: docs/decisions/near-pixels-in-compute.md).
/// VOXTIER_NEAR_TRACE_BLOCK (8, 16 or 32) and VOXTIER_NEAR_TRACE_ROWS (1 to 32, a power of two
/// up to the side) force one shape, for measuring. Throws VulkanError on other values.
NearTraceShape nearTraceShape(const VulkanDevice& device, std::size_t sprites);

/// A compute pass's pipeline; `skipEmpty` matters to the two tracing passes alone, `countSteps`
/// and `traceShape` (its workgroup) to TracePixels alone.
VkPipeline createNearComputePipeline(VkDevice dev, VkPipelineLayout layout, NearComputePass pass,
                                     bool skipEmpty, bool countSteps, NearTraceShape traceShape);

} // namespace voxtier
