#version 450
// The splat and paint passes of cell-rate sprites (DESIGN.md §3.11). Both walk every pixel of
// every cell-rate sprite's screen rectangle, map it to its lattice cell (the kernel's
// vtPixelCell, dither included) and look the cell's outcome up; pixels whose cell is empty are
// skipped. No fragment runs for these sprites (the rasteriser's fixed cost per fragment was most
// of their time).
//  - Splat (before the draw): offer the sprite's depth rank to the pixel with atomicMin. A rank
//    orders the frame's cell-rate sprites nearest first, lower entity id first at equal depth:
//    Image::writeIfNearer's rule, so the least rank is the sprite the depth test would keep.
//  - Paint (compiled with -DVT_PAINT, after the draw's targets are copied into the host-visible
//    readback buffer): the sprite that holds the pixel's least rank writes its colour, entity id
//    and depth there, where it beats what the draw left by the same rule. The sprite is uniform
//    per workgroup, so the shading reads little per pixel.
// A workgroup is one NEAR_SPLAT_BLOCK² block of one sprite's rectangle, 32 x 2 invocations
// walking it two rows at a time: llvmpipe pays about 0.8 µs per workgroup, which at 8 x 8
// pixels per workgroup cost more than the pixels themselves.
#extension GL_GOOGLE_include_directive : require
#include "volumetric/shaders/near_shared.h"

layout(local_size_x = NEAR_SPLAT_BLOCK, local_size_y = 2) in;

// The kernel header needs a voxel source to compile; this pass never traces.
uint vtFetchVoxel(ivec3 cell);
#include "core/sprite_kernel.h"

layout(std430, set = 0, binding = NEAR_BINDING_SPRITES) readonly buffer Sprites {
    SpriteGpu vtSprites[];
};
layout(std430, set = 0, binding = NEAR_BINDING_CELL_BASES) readonly buffer CellBases {
    uint vtCellBases[];
};
layout(std430, set = 0, binding = NEAR_BINDING_CELLS) readonly buffer Cells {
    uint vtCells[];
};
layout(std430, set = 0, binding = NEAR_BINDING_SPLAT_BLOCKS) readonly buffer SplatBlocks {
    NearSplatBlock vtBlocks[];
};
layout(std430, set = 0, binding = NEAR_BINDING_SPLAT_RANKS) readonly buffer SplatRanks {
    uint vtRanks[]; // the depth rank of each sprite (NEAR_NO_RANK for per-pixel ones)
};
layout(std430, set = 0, binding = NEAR_BINDING_PIXEL_RANKS) buffer PixelRanks {
    uint vtPixelRanks[];
};
#ifdef VT_PAINT
layout(std430, set = 0, binding = NEAR_BINDING_PALETTES) readonly buffer Palettes {
    uint vtPalettes[];
};
layout(std430, set = 0, binding = NEAR_BINDING_READBACK) buffer Readback {
    uint vtPlanes[]; // colour, then entity id, then depth bits: width * height each
};
#endif
layout(push_constant) uniform Push {
    NearComputePush vtPush;
};

void main() {
    uint block = gl_WorkGroupID.y * gl_NumWorkGroups.x + gl_WorkGroupID.x;
    if (block >= vtPush.count) return;
    NearSplatBlock b = vtBlocks[block];
    uint x = (b.origin & 0xFFFFu) + gl_LocalInvocationID.x;
    if (x >= (b.end & 0xFFFFu)) return;
    uint yEnd = min(b.end >> 16, (b.origin >> 16) + NEAR_SPLAT_BLOCK);
    SpriteGpu s = vtSprites[b.sprite];
    uint base = vtPush.cells + vtCellBases[b.sprite];
    uint rank = vtRanks[b.sprite];
#ifdef VT_PAINT
    uint plane = vtPush.width * vtPush.height;
#endif
    for (uint y = (b.origin >> 16) + gl_LocalInvocationID.y; y < yEnd; y += 2u) {
        ivec2 cell;
        if (!vtPixelCell(s, vec2(float(x) + 0.5f, float(y) + 0.5f), cell)) continue;
        uint index;
        uint face;
        uint kind = vtUnpackOutcome(vtCells[base + vtCellSlot(s, cell)], index, face);
        if (kind == VT_KIND_EMPTY) continue;
        uint p = y * vtPush.width + x;
#ifdef VT_PAINT
        if (vtPixelRanks[p] != rank) continue;
        float drawnDepth = uintBitsToFloat(vtPlanes[2u * plane + p]);
        if (!(s.depth > drawnDepth || (s.depth == drawnDepth && s.dims.w < vtPlanes[plane + p])))
            continue;
        vtPlanes[p] = kind == VT_KIND_SOLID
                          ? vtLit(vtPalettes[s.atlas.w + index], vtFaceLight(s, face))
                          : VT_OUTLINE_RGBA;
        vtPlanes[plane + p] = s.dims.w;
        vtPlanes[2u * plane + p] = floatBitsToUint(s.depth);
#else
        atomicMin(vtPixelRanks[p], rank);
#endif
    }
}
