#version 450
// The far pass cut by sprite (FarTiles::Sprites; far_blit.comp cuts it by image tile): the same
// image, found in two dispatches with no list of sprites per tile and no walk through one.
// FAR_SPLAT=1: a workgroup per chunk of a far instance's rectangle (FAR_SPLAT_CHUNK pixels: the
// first chunk of every instance, then the list of the others) covers it, FAR_WORKGROUP pixels at
// a time; each pixel the instance would win against what the near tier left there (the
// depth-and-id rule) and draws (farPixelColour) takes the instance's index by atomicMin into the
// pixel's winner word.
// The instances are in the rule's order (far_pass.cpp: nearer first, equal depths by ascending
// id), so the least index among them is the one the rule picks whatever the atomics' order.
// FAR_SPLAT=0: per pixel of the rectangles' bounds, its winner (if any) writes colour, id and
// depth into the planes.
// A pixel's work is its own rectangle's pixels once, wherever the crowd is thick: a tile's
// workgroup in far_blit.comp passes every sprite over the tile one after another.
#extension GL_GOOGLE_include_directive : require

// The kernel header needs a voxel source to compile; this pass never traces.
uint vtFetchVoxel(ivec3 cell);
#include "core/sprite_kernel.h"
#include "impostor_cache/shaders/far_shared.h"

#if !defined(FAR_SPLAT)
#error "build with FAR_SPLAT=1 (the splat) or 0 (the resolve) (impostor_cache/CMakeLists.txt)"
#endif

#include "impostor_cache/shaders/far_pixel.glsl"
layout(std430, set = 0, binding = FAR_BINDING_PLANES) buffer Planes {
    uint vtPlanes[]; // colour, then entity id, then depth bits: width * height each
};
// Per pixel: the least index of the instances that draw it and win it against the near tier,
// FAR_NO_WINNER where none (filled before the splat).
layout(std430, set = 0, binding = FAR_BINDING_WINNERS) coherent buffer Winners {
    uint vtWinners[];
};

#if FAR_SPLAT
layout(local_size_x = FAR_WORKGROUP) in;
// The chunks past each rectangle's first: instance, chunk index (far_shared.h).
layout(std430, set = 0, binding = FAR_BINDING_TILE_LIST) readonly buffer Chunks {
    uint vtChunks[];
};

void main() {
    uint g = gl_WorkGroupID.y * gl_NumWorkGroups.x + gl_WorkGroupID.x;
    if (g >= vtPush.count) return;
    // Workgroup g < instances: instance g's first chunk; the rest, a chunk from the list.
    uint f = g, chunk = 0u;
    if (g >= vtPush.part) {
        f = vtChunks[2u * (g - vtPush.part)];
        chunk = vtChunks[2u * (g - vtPush.part) + 1u];
    }
    ivec4 r = vtFar[f].rect;
    uint w = uint(r.z - r.x);
    uint pixels = w * uint(r.w - r.y);
    uint begin = chunk * FAR_SPLAT_CHUNK;
    uint end = min(pixels, begin + FAR_SPLAT_CHUNK);
    float d = intBitsToFloat(vtFar[f].extra.z);
    uint entity = uint(vtFar[f].extra.w);
    uint plane = vtPush.width * vtPush.height;
    SpriteGpu s = vtSpriteOfFar(vtFar[f].sprite);
    // Pixel i of the rectangle is column i % w, row i / w: divided once, then stepped (a CPU
    // device divides lane by lane).
    uint first = begin + gl_LocalInvocationIndex;
    uint column = first % w, row = first / w;
    uint stepColumns = FAR_WORKGROUP % w, stepRows = FAR_WORKGROUP / w;
    for (uint i = first; i < end; i += FAR_WORKGROUP) {
        int x = r.x + int(column);
        int y = r.y + int(row);
        column += stepColumns;
        row += stepRows;
        if (column >= w) {
            column -= w;
            row += 1u;
        }
        uint p = uint(y) * vtPush.width + uint(x);
        // A nearer instance (a lesser index) that already won the pixel settles it: winners only
        // fall, so whatever value this reads, a lesser one stands at the end. The nearest come
        // first in the dispatch, so in a crowd most pixels are settled before the rest arrive.
        if (vtWinners[p] < f) continue;
        float depth = uintBitsToFloat(vtPlanes[2u * plane + p]);
        if (!(d > depth || (d == depth && entity < vtPlanes[plane + p]))) continue;
        uint colour;
        if (!farPixelColour(f, s, vec2(float(x) + 0.5f, float(y) + 0.5f), colour))
            continue;
        atomicMin(vtWinners[p], f);
    }
}
#else
layout(local_size_x = 8, local_size_y = 8) in;

void main() {
    // Over the far rectangles' bounds, from their first pixel (whole rows of workgroups there).
    uvec2 xy = gl_GlobalInvocationID.xy + uvec2(vtPush.origin & 0xFFFFu, vtPush.origin >> 16);
    if (xy.x >= vtPush.width || xy.y >= vtPush.height) return;
    uint p = xy.y * vtPush.width + xy.x;
    uint f = vtWinners[p];
    if (f == FAR_NO_WINNER) return;
    uint colour;
    farPixelColour(f, vtSpriteOfFar(vtFar[f].sprite), vec2(xy) + 0.5f, colour);
    uint plane = vtPush.width * vtPush.height;
    vtPlanes[p] = colour;
    vtPlanes[plane + p] = uint(vtFar[f].extra.w);
    vtPlanes[2u * plane + p] = uint(vtFar[f].extra.z);
}
#endif
