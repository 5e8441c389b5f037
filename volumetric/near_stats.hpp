#pragma once
// What each near backend reports of the frames it draws: the CPU reference (ReferenceStats) and
// the Vulkan near passes (NearStats). compose's FrameStats holds one of each as the backend
// wrote it; the frame's output columns read them through compose/frame_figures.hpp.
#include "core/near_rate.hpp"

#include <cstdint>

namespace voxtier {

/// What the CPU reference tracer did in one frame.
struct ReferenceStats : CellRateCounts {
    std::uint64_t sprites = 0;        ///< sprites drawn
    std::uint64_t culled = 0;         ///< visible sprites occlusion culling dropped whole
    std::uint64_t pixelsTested = 0;   ///< pixels of sprite rectangles evaluated ("fragments")
    std::uint64_t pixelsHidden = 0;   ///< of those, already nearer: neither traced nor looked up
    std::uint64_t pixelsInSprite = 0; ///< of those, pixels that map to a lattice cell
    std::uint64_t pixelsWritten = 0;  ///< solid or outline outcomes
    std::uint64_t voxelFetches = 0;   ///< reads: DDA steps (one voxel each) and brick reads
    std::uint64_t brickFetches = 0;   ///< of those, reads of the brick occupancy
    double milliseconds = 0.0;
};

/// What the near passes did in one frame (the counts; the device times are the frame's named
/// passes, device/pass_timer.hpp).
struct NearStats : CellRateCounts {
    std::uint64_t sprites = 0; ///< instances drawn
    std::uint64_t drawCalls = 0;
    /// FRAGMENT_SHADER_INVOCATIONS of the draw (0 when the device has no statistics queries).
    std::uint64_t fragmentInvocations = 0;
    /// With countSteps: fragments (or, traced in compute, pixels) that ran the kernel, and their
    /// vtFetchVoxel calls (DDA steps, the four outline neighbour rays included).
    std::uint64_t kernelFragments = 0, voxelFetches = 0;
    std::uint64_t bytesUploaded = 0; ///< voxel bytes copied to the atlas for this frame
    std::uint64_t uploadRegions = 0;
    std::uint64_t atlasGrowths = 0; ///< the atlas was re-created larger this frame
    double uploadMs = 0.0;          ///< residency on the host: pack + copy + wait
    /// Host time of the recording's two halves (both within the frame's host_record_ms): the
    /// sprite records (draw order, residency, each record gathered and written where the
    /// shaders read it), and the lists the passes walk (proxies, the rate plan, the cell store,
    /// the work lists and their uploads, the descriptors).
    double recordSpritesMs = 0.0, recordListsMs = 0.0;
    /// Of recordSpritesMs: the draw order (sorted, or last frame's kept), and the voxel
    /// residency (each model frame's first showing, the atlas's uploads, where each frame lies).
    /// The rest is the records' loop. Which of the three bounds a frame differs by host: a moving
    /// camera reorders every sprite, and the loop writes where the device reads.
    double recordOrderMs = 0.0, recordResidencyMs = 0.0;
    /// Of recordListsMs: the host's arithmetic (the rate plan, the ranks, the cell tiles and the
    /// splat, trace and resolve blocks, all in host memory), and those lists written where the
    /// passes read them. The rest is the proxies (rasterised frames), the cell store's and pixel
    /// words' buffers and the descriptors. On the H200's host the lists took 3 ms at 100,000
    /// tanks against ~2 on two cores here, whose serial passes are ~0.3 ms: which part grows
    /// there is what these tell.
    double recordListsBuildMs = 0.0, recordListsUploadMs = 0.0;
    /// Sprite records left as the frame's slot last held them (unchanged since, in the same
    /// place: not written again), and whether the draw order was last frame's (no sprite set up
    /// anew since). Only where the sprites came with their history (NearPasses::record).
    std::uint64_t recordsKept = 0;
    /// Of the others, records left but for their animation frame's fields (an animation step
    /// since: the voxels' and occupancy's places and the skip rule written).
    std::uint64_t recordsPatched = 0;
    bool drawOrderKept = false;
    /// And the residency's first showing of each model frame (the same frames as well).
    bool firstShowingsKept = false;
    /// Sprites rasterised flat at their depth, with the early depth test (earlyDepthTest).
    std::uint64_t earlyDepthSprites = 0;
    /// The per-pixel sprites were traced by the compute pass (NearPixels::Compute), not drawn.
    bool pixelsInCompute = false;
};

} // namespace voxtier
