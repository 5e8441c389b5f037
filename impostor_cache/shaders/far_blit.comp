#version 450
// The far pass (DESIGN.md §6, the far tier on Vulkan): the far blit of
// impostor_cache/far_blit.cpp on the GPU, pixel for pixel. It runs after the near tier's
// targets are copied into the frame's planes (and after the cell-rate resolve), so it composes
// by the same rule as the CPU blit writing into the near image: Image::writeIfNearer (nearer, or
// as near with the lower entity id), whichever tier drew the pixel before. Per pixel and far
// sprite whose rectangle holds it: the near lattice cell (vtPixelCell, dither included), the
// snapshot cell under that cell's centre (the SnapshotCellMap, in double like the CPU's), and the
// cell's colour (vtLit of the palette entry by the entered face's light, or the outline). A
// workgroup is one 32x32 tile of the image that some far rectangle touches, 32 x 2 invocations,
// each owning every other pixel of one column: it keeps its 16 pixels in registers while the
// tile's far sprites pass over them, so nothing races and the sprites' order does not matter
// (the rule decides).
#extension GL_GOOGLE_include_directive : require

// The kernel header needs a voxel source to compile; this pass never traces.
uint vtFetchVoxel(ivec3 cell);
#include "core/sprite_kernel.h"
#include "impostor_cache/shaders/far_shared.h"

layout(local_size_x = FAR_TILE, local_size_y = 2) in;

layout(std430, set = 0, binding = FAR_BINDING_INSTANCES) readonly buffer Instances {
    FarInstanceGpu vtFar[];
};
layout(std430, set = 0, binding = FAR_BINDING_SNAPSHOTS) readonly buffer Snapshots {
    uint vtSnapshotWords[];
};
layout(std430, set = 0, binding = FAR_BINDING_PALETTES) readonly buffer FarPalettes {
    uint vtFarPalettes[];
};
layout(std430, set = 0, binding = FAR_BINDING_TILES) readonly buffer Tiles {
    FarTile vtTiles[];
};
layout(std430, set = 0, binding = FAR_BINDING_TILE_LIST) readonly buffer TileList {
    uint vtTileList[];
};
layout(std430, set = 0, binding = FAR_BINDING_PLANES) buffer Planes {
    uint vtPlanes[]; // colour, then entity id, then depth bits: width * height each
};
layout(push_constant) uniform Push {
    FarPush vtPush; // count: tiles
};

const uint FAR_EMPTY = 0u;
const uint FAR_SOLID0 = 1u;
const uint FAR_OUTLINE = 7u;
const int FAR_ROWS = int(FAR_TILE) / 2; // rows of a tile per invocation

void main() {
    uint tile = gl_WorkGroupID.y * gl_NumWorkGroups.x + gl_WorkGroupID.x;
    if (tile >= vtPush.count) return;
    uint origin = vtTiles[tile].origin;
    uint first = vtTiles[tile].first;
    uint count = vtTiles[tile].count;
    int x = int((origin & 0xFFFFu) + gl_LocalInvocationID.x);
    if (x >= int(vtPush.width)) return;
    // This invocation's pixels: column x, rows y0, y0 + 2, ... below yEnd (at most 16), kept in
    // registers while the tile's sprites pass over them, sprite by sprite: each sprite's
    // constants are read once, and only its rectangle's rows are visited.
    int y0 = int(origin >> 16) + int(gl_LocalInvocationID.y);
    int yEnd = min(int(vtPush.height), int(origin >> 16) + int(FAR_TILE));
    int rows = yEnd > y0 ? (yEnd - y0 + 1) / 2 : 0;
    uint plane = vtPush.width * vtPush.height;
    uint colors[FAR_ROWS];
    uint ids[FAR_ROWS];
    float depths[FAR_ROWS];
    for (int k = 0; k < rows; ++k) {
        uint p = uint(y0 + 2 * k) * vtPush.width + uint(x);
        colors[k] = vtPlanes[p];
        ids[k] = vtPlanes[plane + p];
        depths[k] = uintBitsToFloat(vtPlanes[2u * plane + p]);
    }
    uint changed = 0u;
    float px = float(x) + 0.5f;
    for (uint e = first; e < first + count; ++e) {
        uint f = vtTileList[e];
        ivec4 r = vtFar[f].rect;
        if (x < r.x || x >= r.z) continue;
        // Rows y0 + 2k inside [r.y, r.w).
        int kFrom = r.y > y0 ? (r.y - y0 + 1) / 2 : 0;
        int kTo = min(rows, r.w > y0 ? (r.w - y0 + 1) / 2 : 0);
        if (kFrom >= kTo) continue;
        SpriteGpu s = vtFar[f].sprite;
        float d = s.depth;
        uint entity = s.dims.w;
        for (int k = kFrom; k < kTo; ++k) {
            // Only a pixel this sprite would win can change (the rule does not depend on order).
            if (!(d > depths[k] || (d == depths[k] && entity < ids[k]))) continue;
            ivec2 cell;
            if (!vtPixelCell(s, vec2(px, float(y0 + 2 * k) + 0.5f), cell)) continue;
            precise double u =
                vtFar[f].u0 + vtFar[f].ui * double(cell.x) + vtFar[f].uj * double(cell.y);
            precise double v =
                vtFar[f].v0 + vtFar[f].vi * double(cell.x) + vtFar[f].vj * double(cell.y);
            int si = int(floor(u)) - int(vtFar[f].snap.w);
            int sj = int(floor(v)) - vtFar[f].extra.x;
            if (si < 0 || si >= int(vtFar[f].snap.y) || sj < 0 || sj >= int(vtFar[f].snap.z))
                continue;
            uint slot = uint(sj) * vtFar[f].snap.y + uint(si);
            uint bits =
                (vtSnapshotWords[vtFar[f].snap.x + (slot >> 1)] >> ((slot & 1u) * 16u)) & 0xFFFFu;
            uint code = bits >> 8;
            if (code == FAR_EMPTY) continue;
            colors[k] = code == FAR_OUTLINE
                            ? VT_OUTLINE_RGBA
                            : vtLit(vtFarPalettes[uint(vtFar[f].extra.y) + (bits & 255u)],
                                    vtFaceLight(s, code - FAR_SOLID0));
            depths[k] = d;
            ids[k] = entity;
            changed |= 1u << uint(k);
        }
    }
    for (int k = 0; k < rows; ++k) {
        if ((changed & (1u << uint(k))) == 0u) continue;
        uint p = uint(y0 + 2 * k) * vtPush.width + uint(x);
        vtPlanes[p] = colors[k];
        vtPlanes[plane + p] = ids[k];
        vtPlanes[2u * plane + p] = floatBitsToUint(depths[k]);
    }
}
