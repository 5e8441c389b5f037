// Constants and buffer layouts shared by the near-tier shaders (volumetric/shaders/near.*) and
// their C++ host (volumetric/near_passes.cpp), written in the common subset of GLSL 4.50 and
// C++ like core/sprite_kernel.h, so a binding number or a field offset exists exactly once.
#ifndef VOXTIER_NEAR_SHARED_H
#define VOXTIER_NEAR_SHARED_H

#ifdef __cplusplus
#include <glm/glm.hpp>

#include <cstddef>
#include <cstdint>
namespace voxtier::near_gpu {
using glm::vec4;
using uint = std::uint32_t;
#define VT_NEAR_CONST inline constexpr
#else
#define VT_NEAR_CONST const
#endif

// Descriptor set 0 of the near pipeline.
VT_NEAR_CONST uint NEAR_BINDING_SPRITES =
    0u; // SpriteGpu[]: the drawn sprites' records, laid out by NearRecords (near_sprites.h)
VT_NEAR_CONST uint NEAR_BINDING_ATLAS = 1u; // usampler3D: R8_UINT voxel atlas (palette indices)
VT_NEAR_CONST uint NEAR_BINDING_PALETTES =
    2u; // uint[]: 256 packed RGBA8 colours per resident model
VT_NEAR_CONST uint NEAR_BINDING_COUNTERS =
    3u;                                     // NearCounters (written by the VT_COUNT_STEPS variant)
VT_NEAR_CONST uint NEAR_BINDING_BOXES = 4u; // NearBox[]: proxy-box corners (box proxy only)
VT_NEAR_CONST uint NEAR_BINDING_HULLS = 5u; // NearHull[]: silhouette polygons (hull proxy, default)
// Cell-rate sprites (core/near_rate.hpp): per sprite the offset of its cells in the cell
// store or NEAR_NO_CELLS; the store (one packed kernel outcome per cell, written by the compute
// pass near_cells.comp, read by near.frag); the compute pass's tiles (sprite, first cell slot).
VT_NEAR_CONST uint NEAR_BINDING_CELL_BASES = 6u;
VT_NEAR_CONST uint NEAR_BINDING_CELLS = 7u;
VT_NEAR_CONST uint NEAR_BINDING_CELL_TILES = 8u;
VT_NEAR_CONST uint NEAR_NO_CELLS = 0xFFFFFFFFu;
// Cells per compute workgroup (one invocation per cell; a tile never spans two sprites).
VT_NEAR_CONST uint NEAR_CELL_TILE = 64u;
// Cell-rate sprites are shaded without the rasteriser (CONTRACT.md §3.11): near_splat.comp takes
// 32x32 pixel blocks of their screen rectangles (NearSplatBlock) and leaves in every pixel one
// word, the least over the cell-rate sprites that cover it of (depth rank, the pixel's cell
// outcome): nearPixelWord. The rank is in the high bits, so the least word is the nearest
// sprite's, and it carries what that sprite shows there. After the draw, near_resolve.comp
// shades each pixel's word into the frame's planes where it beats what the draw left.
VT_NEAR_CONST uint NEAR_BINDING_SPLAT_BLOCKS = 9u;
VT_NEAR_CONST uint NEAR_BINDING_RANK_SPRITES = 10u; // uint[]: sprite index of each depth rank
VT_NEAR_CONST uint NEAR_BINDING_PIXEL_WORDS = 11u;
// The frame's planes (device/gpu_frame.hpp): colour, id and depth words, where the resolve
// composes the cell-rate pixels.
VT_NEAR_CONST uint NEAR_BINDING_PLANES = 12u;
// uint[]: the brick occupancy words (core/sprite_kernel.h vtBrickIndex) of every resident model
// frame, each frame's from its SpriteGpu::brickBase (volumetric/voxel_residency.hpp).
VT_NEAR_CONST uint NEAR_BINDING_BRICKS = 13u;
// uint[]: per place in the draw order, the index of its sprite's record (near_sprites.h).
VT_NEAR_CONST uint NEAR_BINDING_RECORD_OF = 14u;
VT_NEAR_CONST uint NEAR_NO_RANK = 0xFFFFFFFFu; // a pixel word no cell-rate sprite wrote
VT_NEAR_CONST uint NEAR_SPLAT_BLOCK = 32u;     // pixels per side of a splat workgroup
// A pixel word: depth rank << NEAR_RANK_SHIFT | kind | face << 2 | palette index << 5. The
// outcome fields fit 13 bits (kind < 3, face < 8, index < 256); the rank gets the other 19, so a
// frame draws at most NEAR_MAX_CELL_SPRITES sprites cell-rate (kind < 3 keeps every word below
// NEAR_NO_RANK).
VT_NEAR_CONST uint NEAR_RANK_SHIFT = 13u;
VT_NEAR_CONST uint NEAR_MAX_CELL_SPRITES = 1u << (32u - NEAR_RANK_SHIFT);

// Vertices per instance: the quad is a 4-vertex triangle strip (SpriteGpu::quad); the box is a
// 36-vertex triangle list (12 triangles) indexed by NEAR_BOX_TRIANGLES.
VT_NEAR_CONST uint NEAR_QUAD_VERTICES = 4u;
VT_NEAR_CONST uint NEAR_BOX_VERTICES = 36u;
// The hull is a convex polygon of at most NEAR_HULL_MAX_VERTICES corners drawn as a triangle fan
// in a triangle list of NEAR_HULL_MAX_VERTICES - 2 triangles; unused triangles are degenerate.
VT_NEAR_CONST uint NEAR_HULL_MAX_VERTICES = 12u;
VT_NEAR_CONST uint NEAR_HULL_VERTICES = 3u * (NEAR_HULL_MAX_VERTICES - 2u);

// 64-bit counters as (low, high) word pairs: the shader carries into the high word itself, so
// no 64-bit atomics feature is needed and a frame of a billion voxel reads does not wrap.
struct NearCounters {
    uint fetchesLo; // vtFetchVoxel calls (DDA steps incl. the outline neighbour rays)
    uint fetchesHi;
    uint fragmentsLo; // fragment invocations that ran the kernel
    uint fragmentsHi;
};

// The rasterised proxy box of CONTRACT.md §3.10 (measured alternative to the quad): the clip-space
// corners of the model bounds grown by one virtual pixel, corner k = (k & 1, k >> 1 & 1, k >> 2)
// of [-1/sigma, dims + 1/sigma] in voxel space, computed on the CPU in double.
struct NearBox {
    vec4 corner[8];
};

// The hull proxy (the default): the parallel projection of the model box
// onto the sprite plane, grown by the kernel's reach (outline ring + half a cell) and two pixels,
// as clip-space corners of a convex polygon in fan order, computed on the CPU in double.
struct NearHull {
    vec4 corner[NEAR_HULL_MAX_VERTICES];
    uint count; // 3..NEAR_HULL_MAX_VERTICES (the quad proxy: its 4 corners in strip order)
    uint pad0;
    uint pad1;
    uint pad2;
};

// One 32x32 block of a cell-rate sprite's screen rectangle: the sprite, the block's first pixel
// and the rectangle's end (exclusive), x in the low 16 bits and y in the high 16 (images are at
// most 16384 pixels wide). The resolve pass walks blocks too: the 32x32 tiles of the image grid
// that some cell-rate rectangle touches, each once (sprite and rank unused, end = the image's
// size), stored after the splat blocks.
struct NearSplatBlock {
    uint sprite;
    uint origin;
    uint end;
    uint rank; // the sprite's depth rank
};

// Push constants of the compute passes: count = cell tiles (near_cells.comp,
// near_cell_outline.comp) or blocks (near_splat.comp, near_resolve.comp: blocks first to
// first + count - 1); cells = the frame's cell count (the cell store holds the primary outcomes,
// then the full outcomes from index `cells` on).
struct NearComputePush {
    uint count;
    uint width;
    uint height;
    uint cells;
    uint first;
};

#ifndef __cplusplus
// A pixel word from a sprite's depth rank and its cell's outcome as the kernel packs it
// (vtPackOutcome: kind | face << 2 | palette index << 8), and that outcome back from a word.
uint nearPixelWord(uint rank, uint outcome) {
    return (rank << NEAR_RANK_SHIFT) | (outcome & 0x1Fu) | ((outcome >> 8) << 5);
}
uint nearWordOutcome(uint word) {
    return (word & 0x1Fu) | (((word >> 5) & 0xFFu) << 8);
}
#endif

#ifdef __cplusplus
static_assert(sizeof(NearSplatBlock) == 16 && sizeof(NearComputePush) == 20);
static_assert(sizeof(NearHull) == 208 && offsetof(NearHull, count) == 192,
              "NearHull must match the std430 array stride in GLSL");
static_assert(sizeof(NearCounters) == 16 && offsetof(NearCounters, fragmentsLo) == 8);
static_assert(sizeof(NearBox) == 128, "NearBox must match the std430 array stride in GLSL");
} // namespace voxtier::near_gpu
#endif

#endif // VOXTIER_NEAR_SHARED_H
