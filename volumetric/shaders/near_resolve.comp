#version 450
// The resolve pass of cell-rate sprites (CONTRACT.md §3.11), after the draw's targets are copied
// into the frame's planes (device/gpu_frame.hpp): every pixel whose word (near_splat.comp) names a
// cell-rate sprite gets that sprite's colour, entity id and depth where it beats what the draw
// left, by Image::writeIfNearer's rule (nearer, or as near with the lower entity id). It reads
// no geometry: the word holds the winner's rank and outcome. A workgroup is one 32x32 tile of
// the image that some cell-rate rectangle touches (each such tile once: a frame with a few small
// cell-rate sprites resolves a few tiles), 32 x 2 invocations walking it two rows at a time.
#extension GL_GOOGLE_include_directive : require
#include "volumetric/shaders/near_shared.h"

layout(local_size_x = NEAR_SPLAT_BLOCK, local_size_y = 2) in;

// The kernel header needs a voxel source to compile; this pass never traces.
uint vtFetchVoxel(ivec3 cell);
#include "core/sprite_kernel.h"

#include "volumetric/shaders/near_sprites.h"
layout(std430, set = 0, binding = NEAR_BINDING_PALETTES) readonly buffer Palettes {
    uint vtPalettes[];
};
layout(std430, set = 0, binding = NEAR_BINDING_SPLAT_BLOCKS) readonly buffer SplatBlocks {
    NearSplatBlock vtBlocks[];
};
layout(std430, set = 0, binding = NEAR_BINDING_RANK_SPRITES) readonly buffer RankSprites {
    uint vtRankSprites[];
};
layout(std430, set = 0, binding = NEAR_BINDING_PIXEL_WORDS) readonly buffer PixelWords {
    uint vtPixelWords[];
};
layout(std430, set = 0, binding = NEAR_BINDING_PLANES) buffer Planes {
    uint vtPlanes[]; // colour, then entity id, then depth bits: width * height each
};
layout(push_constant) uniform Push {
    NearComputePush vtPush; // count: tiles, from block `first` on
};

void main() {
    uint tile = gl_WorkGroupID.y * gl_NumWorkGroups.x + gl_WorkGroupID.x;
    if (tile >= vtPush.count) return;
    uint origin = vtBlocks[vtPush.first + tile].origin;
    uint x = (origin & 0xFFFFu) + gl_LocalInvocationID.x;
    if (x >= vtPush.width) return;
    uint yEnd = min(vtPush.height, (origin >> 16) + NEAR_SPLAT_BLOCK);
    uint plane = vtPush.width * vtPush.height;
    for (uint y = (origin >> 16) + gl_LocalInvocationID.y; y < yEnd; y += 2u) {
        uint p = y * vtPush.width + x;
        uint word = vtPixelWords[p];
        if (word == NEAR_NO_RANK) continue;
        uint sprite = vtRecordOf[vtRankSprites[word >> NEAR_RANK_SHIFT]];
        float depth = vtSprites[sprite].depth;
        uint entity = vtSprites[sprite].dims.w;
        float drawnDepth = uintBitsToFloat(vtPlanes[2u * plane + p]);
        if (!(depth > drawnDepth || (depth == drawnDepth && entity < vtPlanes[plane + p])))
            continue;
        uint index;
        uint face;
        uint kind = vtUnpackOutcome(nearWordOutcome(word), index, face);
        vtPlanes[p] = kind == VT_KIND_SOLID ? vtLit(vtPalettes[vtSprites[sprite].atlas.w + index],
                                                    vtFaceLight(vtSprites[sprite], face))
                                            : VT_OUTLINE_RGBA;
        vtPlanes[plane + p] = entity;
        vtPlanes[2u * plane + p] = floatBitsToUint(depth);
    }
}
