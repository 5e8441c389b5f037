#version 450
// The last pass of cell-rate sprites (DESIGN.md §3.11), after the draw of the per-pixel sprites
// has been copied to the host-visible readback buffer (colour, id, depth planes): every pixel a
// cell-rate sprite won in near_splat.comp is shaded from that sprite's cell outcome and written
// over the drawn pixel where it is nearer, or as near and lower in entity id
// (Image::writeIfNearer). Pixels nothing drew hold depth 0 and no entity, so a winner always
// lands there. A workgroup is one NEAR_SPLAT_BLOCK² block of the image, 32 x 2 invocations
// walking it two rows at a time (few workgroups: llvmpipe pays about 0.8 µs for each).
#extension GL_GOOGLE_include_directive : require
#include "volumetric/shaders/near_shared.h"

layout(local_size_x = NEAR_SPLAT_BLOCK, local_size_y = 2) in;

uint vtFetchVoxel(ivec3 cell);
#include "core/sprite_kernel.h"

layout(std430, set = 0, binding = NEAR_BINDING_SPRITES) readonly buffer Sprites {
    SpriteGpu vtSprites[];
};
layout(std430, set = 0, binding = NEAR_BINDING_PALETTES) readonly buffer Palettes {
    uint vtPalettes[];
};
layout(std430, set = 0, binding = NEAR_BINDING_CELL_BASES) readonly buffer CellBases {
    uint vtCellBases[];
};
layout(std430, set = 0, binding = NEAR_BINDING_CELLS) readonly buffer Cells {
    uint vtCells[];
};
layout(std430, set = 0, binding = NEAR_BINDING_SPLAT_RANKS) readonly buffer SplatRanks {
    uint vtRanks[];
};
layout(std430, set = 0, binding = NEAR_BINDING_PIXEL_RANKS) readonly buffer PixelRanks {
    uint vtPixelRanks[];
};
layout(std430, set = 0, binding = NEAR_BINDING_READBACK) buffer Readback {
    uint vtPlanes[]; // colour, then entity id, then depth bits: width * height each
};
layout(push_constant) uniform Push {
    NearComputePush vtPush;
};

// Shades pixel (x, y) from the cell-rate sprite that won it in the splat, if that is nearer
// than what the draw left there.
void resolvePixel(uint x, uint y) {
    uint p = y * vtPush.width + x;
    uint rank = vtPixelRanks[p];
    if (rank == NEAR_NO_RANK) return;
    uint sprite = vtRanks[vtPush.count + rank];
    SpriteGpu s = vtSprites[sprite];
    uint plane = vtPush.width * vtPush.height;
    float drawnDepth = uintBitsToFloat(vtPlanes[2u * plane + p]);
    if (!(s.depth > drawnDepth || (s.depth == drawnDepth && s.dims.w < vtPlanes[plane + p])))
        return;
    // The splat found this pixel's cell non-empty; the same floats give the same cell here.
    ivec2 cell;
    vtPixelCell(s, vec2(float(x) + 0.5f, float(y) + 0.5f), cell);
    uint index;
    uint face;
    uint kind = vtUnpackOutcome(vtCells[vtPush.cells + vtCellBases[sprite] + vtCellSlot(s, cell)], index, face);
    vtPlanes[p] = kind == VT_KIND_SOLID ? vtLit(vtPalettes[s.atlas.w + index], vtFaceLight(s, face))
                                        : VT_OUTLINE_RGBA;
    vtPlanes[plane + p] = s.dims.w;
    vtPlanes[2u * plane + p] = floatBitsToUint(s.depth);
}

void main() {
    uint x = gl_WorkGroupID.x * NEAR_SPLAT_BLOCK + gl_LocalInvocationID.x;
    if (x >= vtPush.width) return;
    uint y0 = gl_WorkGroupID.y * NEAR_SPLAT_BLOCK;
    uint yEnd = min(vtPush.height, y0 + NEAR_SPLAT_BLOCK);
    for (uint y = y0 + gl_LocalInvocationID.y; y < yEnd; y += 2u) resolvePixel(x, y);
}
