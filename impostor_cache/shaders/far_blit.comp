#version 450
// The far pass (CONTRACT.md §6, the far tier on Vulkan): the far blit of
// impostor_cache/far_blit.cpp on the GPU, pixel for pixel. It runs after the near tier's
// targets are copied into the frame's planes (and after the cell-rate resolve), so it composes
// by the same rule as the CPU blit writing into the near image: Image::writeIfNearer (nearer, or
// as near with the lower entity id), whichever tier drew the pixel before. Per pixel and far
// sprite whose rectangle holds it: the near lattice cell (vtPixelCell, dither included), the
// snapshot cell under that cell's centre (the SnapshotCellMap, in double like the CPU's), and the
// cell's colour (vtLit of the palette entry by the entered face's light, or the outline). A
// workgroup is one FAR_SIDE x FAR_SIDE tile of the image that some far rectangle touches,
// FAR_SIDE x FAR_LANES_Y invocations (built as 32 x 2 and as 8 x 8, far_shared.h), each owning
// every FAR_LANES_Y-th pixel of one column: it keeps its pixels in registers while the tile's
// far sprites pass over them, so nothing races and the image does not depend on the sprites'
// order (the rule decides); the order, nearest first, only lets an invocation stop early. Built
// with FAR_BATCHED (the fine tiles, a GPU's), the tile's sprite list is read a workgroup's width
// at a time into shared memory, one entry and its rectangle per invocation, so
// that a sprite that misses an invocation's pixels costs it a shared-memory read, not a chain of
// two dependent global reads; the coarse tiles, a CPU device's, read the list directly (on
// lavapipe the barriers cost more than the reads they save: 100,000 tanks' far pass 209-230 ->
// 245-273 ms).
#extension GL_GOOGLE_include_directive : require

// The kernel header needs a voxel source to compile; this pass never traces.
uint vtFetchVoxel(ivec3 cell);
#include "core/sprite_kernel.h"
#include "impostor_cache/shaders/far_shared.h"

#if !defined(FAR_SIDE) || !defined(FAR_LANES_Y) || !defined(FAR_BATCHED) || \
    FAR_SIDE * FAR_LANES_Y != 64
#error "build with FAR_SIDE x FAR_LANES_Y = FAR_WORKGROUP invocations (impostor_cache/CMakeLists.txt)"
#endif
layout(local_size_x = FAR_SIDE, local_size_y = FAR_LANES_Y) in;

#include "impostor_cache/shaders/far_pixel.glsl"
layout(std430, set = 0, binding = FAR_BINDING_TILES) readonly buffer Tiles {
    FarTile vtTiles[];
};
layout(std430, set = 0, binding = FAR_BINDING_TILE_LIST) readonly buffer TileList {
    uint vtTileList[];
};
layout(std430, set = 0, binding = FAR_BINDING_PLANES) buffer Planes {
    uint vtPlanes[]; // colour, then entity id, then depth bits: width * height each
};

const int FAR_ROWS = FAR_SIDE / FAR_LANES_Y; // rows of a tile per invocation
const uint FAR_LIST_STEP = FAR_BATCHED != 0 ? FAR_LIST_STEP_FINE : FAR_LIST_STEP_COARSE;

#if FAR_BATCHED
// One batch of the tile's sprite list: entries, their rectangles and their depth bits and ids.
shared uint batchSprite[FAR_WORKGROUP];
shared ivec4 batchRect[FAR_WORKGROUP];
shared uvec2 batchOrder[FAR_WORKGROUP];
// Invocations whose pixels no later sprite of the tile can change.
shared uint finished;
#endif

// Of an invocation's pixels, the one a sprite wins most easily (the shallowest; of equal depths,
// the greatest id): a sprite that pixel refuses, every one of them refuses. No pixel: +infinity,
// which every sprite is refused by.
void weakestPixel(int rows, float depths[FAR_ROWS], uint ids[FAR_ROWS], out float weakDepth,
                  out uint weakId) {
    weakDepth = uintBitsToFloat(0x7F800000u);
    weakId = 0u;
    for (int k = 0; k < rows; ++k) {
        if (depths[k] < weakDepth || (depths[k] == weakDepth && ids[k] > weakId)) {
            weakDepth = depths[k];
            weakId = ids[k];
        }
    }
}

void main() {
    uint tile = gl_WorkGroupID.y * gl_NumWorkGroups.x + gl_WorkGroupID.x;
    if (tile >= vtPush.count) return; // the whole workgroup: no barrier is skipped
    // This dispatch's part of the tile's list (far_shared.h: lavapipe's loop limit).
    uint listed = vtTiles[tile].count;
    uint skipped = min(listed, vtPush.part * FAR_LIST_STEP);
    uint count = min(listed - skipped, FAR_LIST_STEP);
    if (count == 0u) return; // the whole workgroup
    uint origin = vtTiles[tile].origin;
    uint first = vtTiles[tile].first + skipped;
    int x = int((origin & 0xFFFFu) + gl_LocalInvocationID.x);
    // This invocation's pixels: column x, rows y0, y0 + FAR_LANES_Y, ... below yEnd (at most
    // FAR_ROWS), kept in registers while the tile's sprites pass over them, sprite by sprite:
    // each sprite's constants are read once, and only its rectangle's rows are visited. An
    // invocation past the image's right edge owns no pixel but still loads its share of each
    // batch.
    int y0 = int(origin >> 16) + int(gl_LocalInvocationID.y);
    int yEnd = min(int(vtPush.height), int(origin >> 16) + FAR_SIDE);
    int rows = x < int(vtPush.width) && yEnd > y0 ? (yEnd - y0 + FAR_LANES_Y - 1) / FAR_LANES_Y : 0;
    uint plane = vtPush.width * vtPush.height;
    uint colors[FAR_ROWS];
    uint ids[FAR_ROWS];
    float depths[FAR_ROWS];
    for (int k = 0; k < rows; ++k) {
        uint p = uint(y0 + FAR_LANES_Y * k) * vtPush.width + uint(x);
        colors[k] = vtPlanes[p];
        ids[k] = vtPlanes[plane + p];
        depths[k] = uintBitsToFloat(vtPlanes[2u * plane + p]);
    }
    uint changed = 0u;
    float px = float(x) + 0.5f;
    // The tile's sprites come nearest first, in the rule's order (far_pass.cpp), so once this
    // invocation's weakest pixel refuses a sprite, every later sprite is refused by all its pixels:
    // it stops there (at 100,000 tanks a crowded tile lists thousands of sprites, most behind the
    // first few that cover it).
    float weakDepth;
    uint weakId;
    weakestPixel(rows, depths, ids, weakDepth, weakId);
    bool done = false;
#if FAR_BATCHED
    if (gl_LocalInvocationIndex == 0u) finished = 0u;
    for (uint b = 0u; b < count; b += FAR_WORKGROUP) {
        barrier(); // the previous batch is read by every invocation; `finished` is settled
        // The same value in every invocation (written only between the next two barriers), so
        // the whole workgroup leaves together.
        if (finished == FAR_WORKGROUP) break;
        uint lane = gl_LocalInvocationIndex;
        if (b + lane < count) {
            uint f = vtTileList[first + b + lane];
            batchSprite[lane] = f;
            batchRect[lane] = vtFar[f].rect;
            batchOrder[lane] = uvec2(vtFar[f].extra.zw);
        }
        barrier();
        uint batch = min(FAR_WORKGROUP, count - b);
        for (uint e = 0u; e < batch && !done; ++e) {
            uint f = batchSprite[e];
            ivec4 r = batchRect[e];
            float d = uintBitsToFloat(batchOrder[e].x);
            uint entity = batchOrder[e].y;
#else
    {
        for (uint e = first; e < first + count; ++e) {
            uint f = vtTileList[e];
            ivec4 r = vtFar[f].rect;
            ivec2 order = vtFar[f].extra.zw;
            float d = intBitsToFloat(order.x);
            uint entity = uint(order.y);
#endif
            if (d < weakDepth || (d == weakDepth && entity >= weakId)) {
                done = true;
#if FAR_BATCHED
                atomicAdd(finished, 1u);
#endif
                break;
            }
            if (x < r.x || x >= r.z) continue;
            // Rows y0 + FAR_LANES_Y k inside [r.y, r.w).
            int kFrom = r.y > y0 ? (r.y - y0 + FAR_LANES_Y - 1) / FAR_LANES_Y : 0;
            int kTo = min(rows, r.w > y0 ? (r.w - y0 + FAR_LANES_Y - 1) / FAR_LANES_Y : 0);
            if (kFrom >= kTo) continue;
            SpriteGpu s = vtSpriteOfFar(vtFar[f].sprite);
            uint wrote = 0u;
            for (int k = kFrom; k < kTo; ++k) {
                // Only a pixel this sprite would win can change (the rule does not depend on
                // order).
                if (!(d > depths[k] || (d == depths[k] && entity < ids[k]))) continue;
                uint colour;
                if (!farPixelColour(f, s, vec2(px, float(y0 + FAR_LANES_Y * k) + 0.5f), colour))
                    continue;
                colors[k] = colour;
                depths[k] = d;
                ids[k] = entity;
                wrote |= 1u << uint(k);
            }
            if (wrote != 0u) {
                changed |= wrote;
                weakestPixel(rows, depths, ids, weakDepth, weakId);
            }
        }
    }
    for (int k = 0; k < rows; ++k) {
        if ((changed & (1u << uint(k))) == 0u) continue;
        uint p = uint(y0 + FAR_LANES_Y * k) * vtPush.width + uint(x);
        vtPlanes[p] = colors[k];
        vtPlanes[plane + p] = ids[k];
        vtPlanes[2u * plane + p] = floatBitsToUint(depths[k]);
    }
}
