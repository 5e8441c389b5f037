#version 450
// The far pass (DESIGN.md §6, the far tier on Vulkan): the far blit of
// impostor_cache/far_blit.cpp on the GPU, pixel for pixel. It runs after the near tier's
// targets are copied into the readback buffer (and after the cell-rate resolve), so it composes
// by the same rule as the CPU blit writing into the near image: Image::writeIfNearer (nearer, or
// as near with the lower entity id), whichever tier drew the pixel before. Per pixel and far
// sprite whose rectangle holds it: the near lattice cell (vtPixelCell, dither included), the
// snapshot cell under that cell's centre (the SnapshotCellMap, in double like the CPU's), and the
// cell's colour (vtLit of the palette entry by the entered face's light, or the outline). A
// workgroup is one 32x32 tile of the image that some far rectangle touches, 32 x 2 invocations
// walking it two rows at a time; each pixel is owned by one invocation, so nothing races and the
// sprites' order does not matter (the rule decides).
#extension GL_GOOGLE_include_directive : require
#include "volumetric/shaders/near_shared.h"

layout(local_size_x = NEAR_SPLAT_BLOCK, local_size_y = 2) in;

// The kernel header needs a voxel source to compile; this pass never traces.
uint vtFetchVoxel(ivec3 cell);
#include "core/sprite_kernel.h"
#include "volumetric/shaders/far_shared.h"

layout(std430, set = 0, binding = NEAR_BINDING_FAR_INSTANCES) readonly buffer Instances {
    FarInstanceGpu vtFar[];
};
layout(std430, set = 0, binding = NEAR_BINDING_FAR_SNAPSHOTS) readonly buffer Snapshots {
    uint vtSnapshotWords[];
};
layout(std430, set = 0, binding = NEAR_BINDING_FAR_PALETTES) readonly buffer FarPalettes {
    uint vtFarPalettes[];
};
layout(std430, set = 0, binding = NEAR_BINDING_FAR_TILES) readonly buffer Tiles {
    FarTile vtTiles[];
};
layout(std430, set = 0, binding = NEAR_BINDING_FAR_TILE_LIST) readonly buffer TileList {
    uint vtTileList[];
};
layout(std430, set = 0, binding = NEAR_BINDING_READBACK) buffer Readback {
    uint vtPlanes[]; // colour, then entity id, then depth bits: width * height each
};
layout(push_constant) uniform Push {
    NearComputePush vtPush; // count: tiles
};

const uint FAR_EMPTY = 0u;
const uint FAR_SOLID0 = 1u;
const uint FAR_OUTLINE = 7u;

void main() {
    uint tile = gl_WorkGroupID.y * gl_NumWorkGroups.x + gl_WorkGroupID.x;
    if (tile >= vtPush.count) return;
    uint origin = vtTiles[tile].origin;
    uint first = vtTiles[tile].first;
    uint count = vtTiles[tile].count;
    int x = int((origin & 0xFFFFu) + gl_LocalInvocationID.x);
    if (x >= int(vtPush.width)) return;
    int yEnd = min(int(vtPush.height), int(origin >> 16) + int(NEAR_SPLAT_BLOCK));
    uint plane = vtPush.width * vtPush.height;
    for (int y = int(origin >> 16) + int(gl_LocalInvocationID.y); y < yEnd; y += 2) {
        uint p = uint(y) * vtPush.width + uint(x);
        uint color = vtPlanes[p];
        uint id = vtPlanes[plane + p];
        float depth = uintBitsToFloat(vtPlanes[2u * plane + p]);
        bool changed = false;
        vec2 pc = vec2(float(x) + 0.5f, float(y) + 0.5f);
        for (uint k = first; k < first + count; ++k) {
            uint f = vtTileList[k];
            ivec4 r = vtFar[f].rect;
            if (x < r.x || x >= r.z || y < r.y || y >= r.w) continue;
            float d = vtFar[f].sprite.depth;
            uint e = vtFar[f].sprite.dims.w;
            // Only a pixel this sprite would win can change (the rule does not depend on order).
            if (!(d > depth || (d == depth && e < id))) continue;
            ivec2 cell;
            if (!vtPixelCell(vtFar[f].sprite, pc, cell)) continue;
            precise double u = vtFar[f].u0 + vtFar[f].ui * double(cell.x) + vtFar[f].uj * double(cell.y);
            precise double v = vtFar[f].v0 + vtFar[f].vi * double(cell.x) + vtFar[f].vj * double(cell.y);
            int si = int(floor(u)) - int(vtFar[f].snap.w);
            int sj = int(floor(v)) - vtFar[f].extra.x;
            if (si < 0 || si >= int(vtFar[f].snap.y) || sj < 0 || sj >= int(vtFar[f].snap.z))
                continue;
            uint slot = uint(sj) * vtFar[f].snap.y + uint(si);
            uint bits = (vtSnapshotWords[vtFar[f].snap.x + (slot >> 1)] >> ((slot & 1u) * 16u)) &
                        0xFFFFu;
            uint code = bits >> 8;
            if (code == FAR_EMPTY) continue;
            color = code == FAR_OUTLINE
                        ? VT_OUTLINE_RGBA
                        : vtLit(vtFarPalettes[uint(vtFar[f].extra.y) + (bits & 255u)],
                                vtFaceLight(vtFar[f].sprite, code - FAR_SOLID0));
            depth = d;
            id = e;
            changed = true;
        }
        if (changed) {
            vtPlanes[p] = color;
            vtPlanes[plane + p] = id;
            vtPlanes[2u * plane + p] = floatBitsToUint(depth);
        }
    }
}
