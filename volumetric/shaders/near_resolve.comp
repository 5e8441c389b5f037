#version 450
// The resolve pass of cell-rate sprites (DESIGN.md §3.11), after the draw's targets are copied
// into the host-visible readback buffer: every pixel whose word (near_splat.comp) names a
// cell-rate sprite gets that sprite's colour, entity id and depth where it beats what the draw
// left, by Image::writeIfNearer's rule (nearer, or as near with the lower entity id). It reads
// no geometry: the word holds the winner's rank and outcome, so the pass is a linear walk of the
// image. A workgroup walks NEAR_RESOLVE_SPAN runs of 64 consecutive pixels.
#extension GL_GOOGLE_include_directive : require
#include "volumetric/shaders/near_shared.h"

layout(local_size_x = 64) in;

// The kernel header needs a voxel source to compile; this pass never traces.
uint vtFetchVoxel(ivec3 cell);
#include "core/sprite_kernel.h"

layout(std430, set = 0, binding = NEAR_BINDING_SPRITES) readonly buffer Sprites {
    SpriteGpu vtSprites[];
};
layout(std430, set = 0, binding = NEAR_BINDING_PALETTES) readonly buffer Palettes {
    uint vtPalettes[];
};
layout(std430, set = 0, binding = NEAR_BINDING_RANK_SPRITES) readonly buffer RankSprites {
    uint vtRankSprites[];
};
layout(std430, set = 0, binding = NEAR_BINDING_PIXEL_WORDS) readonly buffer PixelWords {
    uint vtPixelWords[];
};
layout(std430, set = 0, binding = NEAR_BINDING_READBACK) buffer Readback {
    uint vtPlanes[]; // colour, then entity id, then depth bits: width * height each
};
layout(push_constant) uniform Push {
    NearComputePush vtPush; // count: workgroups
};

void main() {
    uint group = gl_WorkGroupID.y * gl_NumWorkGroups.x + gl_WorkGroupID.x;
    if (group >= vtPush.count) return;
    uint plane = vtPush.width * vtPush.height;
    uint first = group * NEAR_RESOLVE_SPAN * 64u + gl_LocalInvocationID.x;
    uint end = min(plane, first + NEAR_RESOLVE_SPAN * 64u);
    for (uint p = first; p < end; p += 64u) {
        uint word = vtPixelWords[p];
        if (word == NEAR_NO_RANK) continue;
        uint sprite = vtRankSprites[word >> NEAR_RANK_SHIFT];
        float depth = vtSprites[sprite].depth;
        uint entity = vtSprites[sprite].dims.w;
        float drawnDepth = uintBitsToFloat(vtPlanes[2u * plane + p]);
        if (!(depth > drawnDepth || (depth == drawnDepth && entity < vtPlanes[plane + p])))
            continue;
        uint kind = word & 3u;
        uint face = (word >> 2) & 7u;
        uint index = (word >> 5) & 255u;
        vtPlanes[p] = kind == VT_KIND_SOLID ? vtLit(vtPalettes[vtSprites[sprite].atlas.w + index],
                                                    vtFaceLight(vtSprites[sprite], face))
                                            : VT_OUTLINE_RGBA;
        vtPlanes[plane + p] = entity;
        vtPlanes[2u * plane + p] = floatBitsToUint(depth);
    }
}
