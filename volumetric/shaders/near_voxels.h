// The kernel's voxel source for the near shaders that trace (near.frag, near_cells.comp,
// near_trace.comp), included before core/sprite_kernel.h: the model frame's block of the shared
// atlas and its brick occupancy words, both origins per sprite (main() sets them before
// tracing). Compiled with VT_COUNT_STEPS, every read is counted (a brick read counts as a voxel
// read) and the counters buffer with its 64-bit add is declared.
#ifndef VOXTIER_NEAR_VOXELS_H
#define VOXTIER_NEAR_VOXELS_H

layout(set = 0, binding = NEAR_BINDING_ATLAS) uniform usampler3D vtAtlas;
layout(std430, set = 0, binding = NEAR_BINDING_BRICKS) readonly buffer Bricks {
    uint vtBricks[];
};

ivec3 vtAtlasBase;
uint vtBrickBase;
#ifdef VT_COUNT_STEPS
uint vtFetches = 0u;
#endif
uint vtFetchVoxel(ivec3 cell) {
#ifdef VT_COUNT_STEPS
    vtFetches += 1u;
#endif
    return texelFetch(vtAtlas, vtAtlasBase + cell, 0).r;
}
uint vtFetchBrickWord(uint word) {
#ifdef VT_COUNT_STEPS
    vtFetches += 1u;
#endif
    return vtBricks[vtBrickBase + word];
}

#ifdef VT_COUNT_STEPS
layout(std430, set = 0, binding = NEAR_BINDING_COUNTERS) buffer Counters {
    NearCounters vtCounters;
};
// 64-bit add on a (low, high) pair of the voxel reads (which 0) or the kernel runs (which 1):
// the returned old low word tells whether this add wrapped.
void vtCount64(uint which, uint amount) {
    if (amount == 0u) return;
    if (which == 0u) {
        uint old = atomicAdd(vtCounters.fetchesLo, amount);
        if (old > 0xFFFFFFFFu - amount) atomicAdd(vtCounters.fetchesHi, 1u);
    } else {
        uint old = atomicAdd(vtCounters.fragmentsLo, amount);
        if (old > 0xFFFFFFFFu - amount) atomicAdd(vtCounters.fragmentsHi, 1u);
    }
}
#endif

#endif // VOXTIER_NEAR_VOXELS_H
