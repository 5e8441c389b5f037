// The far pass's bindings, per-sprite and per-tile records and push constants (far_blit.comp and
// its C++ host, impostor_cache/far_pass.cpp), in the common subset of GLSL 4.50 and C++ like
// core/sprite_kernel.h, so a binding number or a field offset exists exactly once. Included after
// core/sprite_kernel.h (a far sprite carries fields of its SpriteGpu).
#ifndef VOXTIER_FAR_SHARED_H
#define VOXTIER_FAR_SHARED_H

#ifdef __cplusplus
#include "core/sprite_kernel.h"

#include <cstddef>
#include <cstdint>
namespace voxtier::far_gpu {
using kernel::ivec4;
using kernel::SpriteGpu;
using kernel::uint;
using kernel::uvec4;
using kernel::vec3;
#define VT_FAR_CONST inline constexpr
#else
#define VT_FAR_CONST const
#endif

// Descriptor set 0 of the far pass.
VT_FAR_CONST uint FAR_BINDING_INSTANCES = 0u; // FarInstanceGpu[]: the frame's far sprites
VT_FAR_CONST uint FAR_BINDING_SNAPSHOTS = 1u; // uint[]: the device-resident snapshot cells
VT_FAR_CONST uint FAR_BINDING_PALETTES = 2u;  // uint[]: the frame's far palettes
VT_FAR_CONST uint FAR_BINDING_TILES = 3u;     // FarTile[]: the image tiles far sprites touch
// uint[]: per tile, the far sprites touching it; cut by sprite, the chunks of the rectangles
// past each one's first (FAR_SPLAT_CHUNK): the instance, then the chunk's index in its rectangle
VT_FAR_CONST uint FAR_BINDING_TILE_LIST = 4u;
VT_FAR_CONST uint FAR_BINDING_PLANES = 5u;  // uint[]: the frame's colour, id, depth planes
VT_FAR_CONST uint FAR_BINDING_WINNERS = 6u; // uint[]: per pixel, far_splat.comp's winner
// A pixel no far instance draws and wins (far_splat.comp).
VT_FAR_CONST uint FAR_NO_WINNER = 0xFFFFFFFFu;
// Pixels per side of a tile, one workgroup of FAR_WORKGROUP invocations each. Coarse: 32 x 2
// invocations, each owning 16 pixels of a column (the fewest invocation steps per sprite: what a
// CPU device runs fastest). Fine: 8 x 8 invocations, a pixel each; a tile lists only the sprites
// within its 8 x 8 pixels, so on a GPU, where a tile's sprites pass one after another through
// its workgroup, a crowd of small far sprites is spread over 16 times as many workgroups.
VT_FAR_CONST uint FAR_TILE_COARSE = 32u;
VT_FAR_CONST uint FAR_TILE_FINE = 8u;
VT_FAR_CONST uint FAR_WORKGROUP = 64u;
// Lavapipe (llvmpipe) ends an invocation's loops once they have run 65,535 iterations between
// them, all loops of the shader counted together, and says nothing: a longer walk leaves pixels
// undrawn. So no invocation of the far pass loops more than a part of that. A tile's workgroup
// walks at most FAR_LIST_STEP_* entries of its list per dispatch (the host dispatches the tiles
// again for the rest, FarPush::part; the pixels are read from the planes each time, and the rule
// does not depend on order): coarse, an entry costs up to 33 iterations (the entry, 16 rows, 16
// rows again for the weakest pixel); fine, up to 3 (and one per batch of 64).
VT_FAR_CONST uint FAR_LIST_STEP_COARSE = 1024u;
VT_FAR_CONST uint FAR_LIST_STEP_FINE = 8192u;
// The pass cut by sprite covers a rectangle in chunks of this many pixels, a workgroup each
// (16 steps of its FAR_WORKGROUP invocations): a rectangle in one workgroup was walked by one
// multiprocessor while the others idled. On the H200 (run 15) the far pass of the street under
// the 1 vpx budget took 1.48 ms of device time, all-near's whole frame 0.28: its largest far
// sprite covers up to ~160,000 pixels, 2,500 steps of one workgroup's 64 invocations.
VT_FAR_CONST uint FAR_SPLAT_CHUNK = 1024u;

// What the far pass reads of a far sprite's SpriteGpu (vtPixelCell's map, range and dither,
// vtFaceLight's factors), copied field for field: 96 bytes of its 208. The host writes one a
// far sprite every frame the camera moves (100,000 tanks under the error budget: ~80,000 far),
// and the rest of a SpriteGpu (the ray's set-up, the atlas) only the near tier reads.
struct FarSpriteGpu {
    vec3 mapI;
    float depth;
    vec3 mapJ;
    float denMax;
    vec3 mapDen;
    float fade;
    ivec4 cellRange;
    uvec4 faceLight0;
    uint faceLight4; // faceLight1.x
    uint faceLight5; // faceLight1.y
    float fadeSide;
    uint unused;
};

#ifdef __cplusplus
inline FarSpriteGpu farSpriteOf(const SpriteGpu& s) {
    return {s.mapI,      s.depth,      s.mapJ,         s.denMax,       s.mapDen,   s.fade,
            s.cellRange, s.faceLight0, s.faceLight1.x, s.faceLight1.y, s.fadeSide, 0u};
}
#else
// The SpriteGpu that vtPixelCell and vtFaceLight read, from the far sprite's copy of those fields
// (the others are never read here).
SpriteGpu vtSpriteOfFar(FarSpriteGpu f) {
    SpriteGpu s;
    s.mapI = f.mapI;
    s.depth = f.depth;
    s.mapJ = f.mapJ;
    s.denMax = f.denMax;
    s.mapDen = f.mapDen;
    s.fade = f.fade;
    s.fadeSide = f.fadeSide;
    s.cellRange = f.cellRange;
    s.faceLight0 = f.faceLight0;
    s.faceLight1 = uvec4(f.faceLight4, f.faceLight5, 0u, 0u);
    return s;
}
#endif

// One far sprite: `sprite` holds what the far pass reads of its SpriteGpu; the snapshot cell of
// near cell (i, j) is (floor(u0 + ui i + uj j), floor(v0 + vi i + vj j)) in double, the far
// blit's SnapshotCellMap; the snapshot's cells (two bytes each: palette index, code; two per
// word) start at word snap.x of the snapshot buffer, snap.y cells a row, snap.z rows, its first
// cell is lattice cell (snap.w, extra.x); its palette starts at extra.y. extra.z and extra.w are
// the sprite's depth (its bits) and entity id, beside its rectangle, for the order test: the
// instances are in the depth-and-id rule's order, nearest first, and so is every tile's list
// (the shader stops at the first sprite a pixel refuses).
struct FarInstanceGpu {
    FarSpriteGpu sprite;
    double u0;
    double ui;
    double uj;
    double v0;
    double vi;
    double vj;
    ivec4 rect;  // screen rectangle x0, y0, x1, y1 (half-open), clipped to the image
    uvec4 snap;  // word offset, width, height, first cell i
    ivec4 extra; // first cell j, palette base, depth bits, entity id
};

// Push constants: the workgroups to run (tiles; cut by sprite, the instances and the chunks
// past their first), the image size, which part of each tile's list this dispatch walks
// (FAR_LIST_STEP_* entries from part * FAR_LIST_STEP_*; cut by sprite, the instance count: the
// workgroups from there take their chunk from the list), and the resolve's first pixel
// (far_splat.comp: x low 16 bits, y high 16).
struct FarPush {
    uint count;
    uint width;
    uint height;
    uint part;
    uint origin;
};

// One 32x32 tile of the image that far sprites touch: its first pixel (x low 16 bits, y high 16)
// and its far sprites, entries first .. first + count - 1 of the tile list.
struct FarTile {
    uint origin;
    uint first;
    uint count;
    uint pad;
};

#ifdef __cplusplus
static_assert(sizeof(FarSpriteGpu) == 96 && offsetof(FarSpriteGpu, cellRange) == 48 &&
                  offsetof(FarSpriteGpu, faceLight4) == 80 &&
                  offsetof(FarSpriteGpu, fadeSide) == 88,
              "FarSpriteGpu must match the std430 layout in GLSL");
static_assert(sizeof(FarInstanceGpu) == 192 && offsetof(FarInstanceGpu, u0) == 96 &&
                  offsetof(FarInstanceGpu, rect) == 144 && offsetof(FarInstanceGpu, extra) == 176,
              "FarInstanceGpu must match the std430 layout in GLSL");
static_assert(sizeof(FarTile) == 16 && sizeof(FarPush) == 20);
} // namespace voxtier::far_gpu
#endif

#endif // VOXTIER_FAR_SHARED_H
