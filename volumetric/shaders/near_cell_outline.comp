#version 450
// The outline pass of cell-rate sprites (CONTRACT.md §3.11), between near_cells.comp and
// near_splat.comp: every cell's full outcome (vtShadeCell's, packed) from its own primary outcome
// and its four cardinal neighbours' (core/sprite_kernel.h vtOutcomeFromPrimaries). The store
// holds the primaries at [cell base + slot] and the outcomes vtPush.cells further on. One
// invocation per cell, in the tiles of near_cells.comp.
#extension GL_GOOGLE_include_directive : require
#include "volumetric/shaders/near_shared.h"

layout(local_size_x = 64) in; // NEAR_CELL_TILE

// The kernel header needs a voxel source to compile; this pass never traces.
uint vtFetchVoxel(ivec3 cell);
#include "core/sprite_kernel.h"

#include "volumetric/shaders/near_sprites.h"
layout(std430, set = 0, binding = NEAR_BINDING_CELL_BASES) readonly buffer CellBases {
    uint vtCellBases[];
};
layout(std430, set = 0, binding = NEAR_BINDING_CELLS) buffer Cells {
    uint vtCells[];
};
layout(std430, set = 0, binding = NEAR_BINDING_CELL_TILES) readonly buffer CellTiles {
    uvec2 vtTiles[]; // (sprite index, first cell slot)
};
layout(push_constant) uniform Push {
    NearComputePush vtPush; // count: tiles
};

uint primaryAt(SpriteGpu s, uint base, ivec2 cell) {
    return vtCellInRange(s, cell) ? vtCells[base + vtCellSlot(s, cell)] : VT_KIND_EMPTY;
}

void main() {
    uint tile = gl_WorkGroupID.y * gl_NumWorkGroups.x + gl_WorkGroupID.x;
    if (tile >= vtPush.count) return;
    uvec2 t = vtTiles[tile];
    SpriteGpu s = vtSprites[vtRecordOf[t.x]];
    uint slot = t.y + gl_LocalInvocationID.x;
    uint rows = uint(s.cellRange.w - s.cellRange.z + 1);
    if (slot >= rows * vtCellRowLength(s)) return;
    uint base = vtCellBases[t.x];
    ivec2 c = vtSlotCell(s, slot);
    vtCells[vtPush.cells + base + slot] = vtOutcomeFromPrimaries(
        primaryAt(s, base, c), primaryAt(s, base, c + ivec2(-1, 0)),
        primaryAt(s, base, c + ivec2(1, 0)), primaryAt(s, base, c + ivec2(0, -1)),
        primaryAt(s, base, c + ivec2(0, 1)));
}
