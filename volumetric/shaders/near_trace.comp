#version 450
// The trace pass of per-pixel sprites without the rasteriser (NearPixels::Compute, CONTRACT.md
// §3.11): every pixel of every per-pixel sprite's screen rectangle runs the shared kernel
// (core/sprite_kernel.h vtShadePixel, at the pixel's centre as a fragment would) and leaves
// atomicMin of its pixel word (near_shared.h: the sprite's depth rank above the outcome) where
// the sprite shows something. The ranks order all the frame's sprites, cell-rate and per-pixel,
// nearest first and lower entity id first at equal depth (Image::writeIfNearer's rule), so the
// least word is what the depth test would keep; near_resolve.comp shades it. A pixel whose word
// already holds a nearer rank is skipped untraced: the word only falls, so the skip is exact
// whatever order the workgroups run in (the blocks are recorded nearest first, so that it pays).
// Why not the fragment shader: docs/decisions/near-pixels-in-compute.md.
// A workgroup is one square block of one sprite's rectangle (NearTraceShape: 32 pixels a side
// on a CPU device, 8 on a GPU).
// Compiled with VT_COUNT_STEPS too: the variant that counts traced pixels and their voxel reads,
// and with VT_SKIP_EMPTY (the box march).
#extension GL_GOOGLE_include_directive : require
#include "volumetric/shaders/near_shared.h"

// The workgroup's shape (specialization constants, NearTraceShape): constant 1 the block's side
// in pixels, constant 0 the rows it runs at once, walking the block that many at a time. A CPU
// device pays per workgroup invocation and takes 32-pixel blocks two rows at a time; a GPU runs
// invocations side by side and takes 8x8 blocks a pixel each, so that a sprite of a few pixels
// occupies few idle lanes.
layout(local_size_x_id = 1, local_size_y_id = 0) in;

#include "volumetric/shaders/near_voxels.h"
#include "core/sprite_kernel.h"

#include "volumetric/shaders/near_sprites.h"
layout(std430, set = 0, binding = NEAR_BINDING_SPLAT_BLOCKS) readonly buffer SplatBlocks {
    NearSplatBlock vtBlocks[];
};
layout(std430, set = 0, binding = NEAR_BINDING_PIXEL_WORDS) buffer PixelWords {
    uint vtPixelWords[];
};
layout(push_constant) uniform Push {
    NearComputePush vtPush; // count: blocks, from block `first` on
};

void main() {
    uint block = gl_WorkGroupID.y * gl_NumWorkGroups.x + gl_WorkGroupID.x;
    if (block >= vtPush.count) return;
    NearSplatBlock b = vtBlocks[vtPush.first + block];
    uint x = (b.origin & 0xFFFFu) + gl_LocalInvocationID.x;
    if (x >= (b.end & 0xFFFFu)) return;
    uint yEnd = min(b.end >> 16, (b.origin >> 16) + gl_WorkGroupSize.x);
    SpriteGpu s = vtSprites[vtRecordOf[b.sprite]];
    vtAtlasBase = ivec3(s.atlas.xyz);
    vtBrickBase = s.brickBase;
#ifdef VT_COUNT_STEPS
    uint traced = 0u;
#endif
    for (uint y = (b.origin >> 16) + gl_LocalInvocationID.y; y < yEnd; y += gl_WorkGroupSize.y) {
        uint p = y * vtPush.width + x;
#ifndef VT_COUNT_STEPS
        // A nearer sprite already shows something here: this one cannot win the pixel. (The
        // counting variant traces every pixel, as the reference without its early depth test,
        // so that its counts do not depend on the order the workgroups ran in.)
        if ((vtPixelWords[p] >> NEAR_RANK_SHIFT) < b.rank) continue;
#endif
        uint index;
        uint face;
        uint kind = vtShadePixel(s, vec2(float(x) + 0.5f, float(y) + 0.5f), index, face);
#ifdef VT_COUNT_STEPS
        traced += 1u;
#endif
        if (kind == VT_KIND_EMPTY) continue;
        // The outcome as the cell-rate passes pack it: index and face only where solid, so that
        // no bit of them can reach the rank's (nearPixelWord keeps the low 13 bits of outcome).
        uint outcome = kind == VT_KIND_SOLID ? vtPackOutcome(kind, index & 255u, face & 7u)
                                             : vtPackOutcome(VT_KIND_OUTLINE, 0u, 0u);
        atomicMin(vtPixelWords[p], nearPixelWord(b.rank, outcome));
    }
#ifdef VT_COUNT_STEPS
    vtCount64(0u, vtFetches);
    vtCount64(1u, traced);
#endif
}
