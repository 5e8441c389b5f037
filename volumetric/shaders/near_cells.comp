#version 450
// The compute pass of cell-rate sprites (core/near_rate.hpp, CONTRACT.md §3.11): every
// lattice cell of every cell-rate sprite of the frame traced once by the shared kernel
// (core/sprite_kernel.h vtTraceCellPrimary: the primary ray only; near_cell_outline.comp adds
// the outline from the neighbours' primaries, which are exactly vtShadeCell's neighbour rays). One invocation per cell; a workgroup is one tile of NEAR_CELL_TILE consecutive cells of
// one sprite (looping over more cells per invocation measured slower on lavapipe).
#extension GL_GOOGLE_include_directive : require
#include "volumetric/shaders/near_shared.h"

layout(local_size_x = 64) in; // NEAR_CELL_TILE

#include "volumetric/shaders/near_voxels.h"
#include "core/sprite_kernel.h"

#include "volumetric/shaders/near_sprites.h"
layout(std430, set = 0, binding = NEAR_BINDING_CELL_BASES) readonly buffer CellBases {
    uint vtCellBases[];
};
layout(std430, set = 0, binding = NEAR_BINDING_CELLS) writeonly buffer Cells {
    uint vtCells[];
};
layout(std430, set = 0, binding = NEAR_BINDING_CELL_TILES) readonly buffer CellTiles {
    uvec2 vtTiles[]; // (sprite index, first cell slot)
};
layout(push_constant) uniform Push {
    NearComputePush vtPush; // count: tiles
};

void main() {
    uint tile = gl_WorkGroupID.y * gl_NumWorkGroups.x + gl_WorkGroupID.x;
    if (tile >= vtPush.count) return;
    uvec2 t = vtTiles[tile];
    SpriteGpu s = vtSprites[vtRecordOf[t.x]];
    uint slot = t.y + gl_LocalInvocationID.x;
    uint rows = uint(s.cellRange.w - s.cellRange.z + 1);
    if (slot >= rows * vtCellRowLength(s)) return;
    vtAtlasBase = ivec3(s.atlas.xyz);
    vtBrickBase = s.brickBase;
    vtCells[vtCellBases[t.x] + slot] = vtTraceCellPrimary(s, vtSlotCell(s, slot));
}
