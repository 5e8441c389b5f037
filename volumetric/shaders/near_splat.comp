#version 450
// The splat pass of cell-rate sprites (CONTRACT.md §3.11). It walks every pixel of every cell-rate
// sprite's screen rectangle, maps it to its lattice cell (the kernel's vtPixelCell, dither
// included) and looks the cell's outcome up; pixels whose cell is empty are skipped. Every other
// pixel gets atomicMin of its pixel word (near_shared.h): the sprite's depth rank above the
// outcome. A rank orders the frame's cell-rate sprites nearest first, lower entity id first at
// equal depth: Image::writeIfNearer's rule, so the least word is the sprite the depth test would
// keep, with what it shows there. No fragment runs for these sprites (the rasteriser's fixed cost
// per fragment was most of their time); near_resolve.comp shades the words after the draw.
// A workgroup is one NEAR_SPLAT_BLOCK² block of one sprite's rectangle, 32 x 2 invocations
// walking it two rows at a time: llvmpipe pays about 0.8 µs per workgroup, which at 8 x 8
// pixels per workgroup cost more than the pixels themselves.
#extension GL_GOOGLE_include_directive : require
#include "volumetric/shaders/near_shared.h"

layout(local_size_x = NEAR_SPLAT_BLOCK, local_size_y = 2) in;

// The kernel header needs a voxel source to compile; this pass never traces.
uint vtFetchVoxel(ivec3 cell);
#include "core/sprite_kernel.h"

#include "volumetric/shaders/near_sprites.h"
layout(std430, set = 0, binding = NEAR_BINDING_CELL_BASES) readonly buffer CellBases {
    uint vtCellBases[];
};
layout(std430, set = 0, binding = NEAR_BINDING_CELLS) readonly buffer Cells {
    uint vtCells[];
};
layout(std430, set = 0, binding = NEAR_BINDING_SPLAT_BLOCKS) readonly buffer SplatBlocks {
    NearSplatBlock vtBlocks[];
};
layout(std430, set = 0, binding = NEAR_BINDING_PIXEL_WORDS) buffer PixelWords {
    uint vtPixelWords[];
};
layout(push_constant) uniform Push {
    NearComputePush vtPush;
};

void main() {
    uint block = gl_WorkGroupID.y * gl_NumWorkGroups.x + gl_WorkGroupID.x;
    if (block >= vtPush.count) return;
    NearSplatBlock b = vtBlocks[vtPush.first + block];
    uint x = (b.origin & 0xFFFFu) + gl_LocalInvocationID.x;
    if (x >= (b.end & 0xFFFFu)) return;
    uint yEnd = min(b.end >> 16, (b.origin >> 16) + NEAR_SPLAT_BLOCK);
    SpriteGpu s = vtSprites[vtRecordOf[b.sprite]];
    uint base = vtPush.cells + vtCellBases[b.sprite];
    for (uint y = (b.origin >> 16) + gl_LocalInvocationID.y; y < yEnd; y += 2u) {
        ivec2 cell;
        if (!vtPixelCell(s, vec2(float(x) + 0.5f, float(y) + 0.5f), cell)) continue;
        uint index;
        uint face;
        uint outcome = vtCells[base + vtCellSlot(s, cell)];
        if (vtUnpackOutcome(outcome, index, face) == VT_KIND_EMPTY) continue;
        atomicMin(vtPixelWords[y * vtPush.width + x], nearPixelWord(b.rank, outcome));
    }
}
