#pragma once
// The near tier's pipelines: the draw's graphics pipeline per proxy and shader variant, and the
// cell-rate compute passes' pipelines, built from the SPIR-V compiled at build time. NearPasses
// caches them (created on first use); this file only builds them.
#include "device/vulkan_device.hpp"
#include "volumetric/near_proxy.hpp"

#include <vulkan/vulkan.h>

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
/// A compute pass's pipeline; `skipEmpty` matters to the two tracing passes alone, `countSteps`
/// to TracePixels alone (its variant counting traced pixels and voxel reads).
VkPipeline createNearComputePipeline(VkDevice dev, VkPipelineLayout layout, NearComputePass pass,
                                     bool skipEmpty, bool countSteps);

} // namespace voxtier
