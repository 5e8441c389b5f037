// The per-pixel sprite kernel of CONTRACT.md §3.4-§3.7, written ONCE in the common subset of
// GLSL 4.50 and C++20 (GLM mirrors GLSL). The Vulkan fragment shader includes this file, and
// so do the CPU reference tracer and the far-tier blit, so every tier evaluates the same IEEE
// float operations in the same order. That is what makes "Vulkan image == reference image,
// pixel for pixel" a property of the code rather than of luck. Rules for editing this file:
//   * only +, -, *, / on floats, floor, min, max, comparisons and int/uint arithmetic; no dot(),
//     length(), normalize(), fma or transcendental functions (their rounding is implementation
//     defined in GLSL), no round() (.5 direction is implementation defined);
//   * float literals carry an `f` suffix (otherwise C++ would compute in double);
//   * every float intermediate that decides a pixel is VT_PRECISE (GLSL `precise` forbids the
//     driver from fusing or reassociating; the C++ side is built with -ffp-contract=off);
//   * no inf/NaN is ever produced: zero direction components take their own branch (HARD_CASES
//     DDA rule 2) and all per-sprite inputs are finite and free of subnormals.
// Per-entity values are prepared in double precision on the CPU (core/sprite.cpp) and rounded
// once into SpriteGpu, the std430 struct both sides read.
#ifndef VOXTIER_SPRITE_KERNEL_H
#define VOXTIER_SPRITE_KERNEL_H

#ifdef __cplusplus
#include <glm/glm.hpp>

#include <cstddef>
#include <cstdint>
namespace voxtier::kernel {
using glm::ivec2;
using glm::ivec3;
using glm::ivec4;
using glm::uvec4;
using glm::vec2;
using glm::vec3;
using glm::vec4;
using uint = std::uint32_t;
using glm::clamp;
using glm::floor;
using glm::max;
using glm::min;
#define VT_PRECISE
#define VT_IN(T) const T&
#define VT_OUT(T) T&
#define VT_CONST inline constexpr
#define VT_FN inline
#else
#define VT_PRECISE precise
#define VT_IN(T) in T
#define VT_OUT(T) out T
#define VT_CONST const
#define VT_FN
#endif

// Outcome of one pixel of one sprite (§3.7).
VT_CONST uint VT_KIND_EMPTY = 0u;   // nothing written (the fragment is discarded)
VT_CONST uint VT_KIND_SOLID = 1u;   // a voxel was hit: palette colour x face light
VT_CONST uint VT_KIND_OUTLINE = 2u; // a cardinal neighbour cell hit: black
VT_CONST uint VT_OUTLINE_RGBA = 0xFF000000u;
VT_CONST uint VT_NO_ENTITY = 0xFFFFFFFFu;
VT_CONST float VT_FAR = 3.0e38f;     // "never" for axes the ray does not move along
VT_CONST uint VT_LIGHT_ONE = 65536u; // face light factors are 16.16 fixed point

// Per-entity, per-frame sprite description (std430; every vec3 is followed by a scalar so the
// C++ and GLSL layouts coincide, see the static_asserts below).
struct SpriteGpu {
    vec3 mapI;   // sigma*(u - g_u) = (mapI . (x, y, 1)) / (mapDen . (x, y, 1)), x, y = pixel centre
    float depth; // reversed-Z clip depth of the model centre (§3.8), written for every pixel
    vec3 mapJ;   // same for sigma*(v - g_v)
    float denMax;   // larger denominators hit the sprite plane nearer than 2*zNear: not drawn
    vec3 mapDen;    // denominator: the pixel ray's component along the view direction
    float fade;     // cross-fade share in (0, 1) while the entity changes tier, 0 otherwise
    vec3 rayBase;   // voxel-space origin of the ray of cell (i, j) is rayBase + ((i+.5) cellRight +
                    // (j+.5) cellUp)
    float fadeSide; // > 0: draw the pixels whose dither threshold is below `fade`; else the others
    vec3 cellRight; // sprite right / sigma (voxel space)
    float reserved2;
    vec3 cellUp; // sprite up / sigma (voxel space)
    float reserved3;
    vec3 dir; // ray direction d (voxel space; components below 1e-6 are exactly 0)
    float reserved4;
    vec3 invDir; // 1/d per axis, 0 where d is 0
    float reserved5;
    ivec4 cellRange;  // iMin, iMax, jMin, jMax: every cell that can be non-empty, inclusive
    uvec4 dims;       // model size x, y, z; w = entity id
    uvec4 atlas;      // xyz: offset of this model frame in the voxel atlas; w: palette base
    uvec4 faceLight0; // 16.16 light factor per entered-face code 0..3
    uvec4 faceLight1; // face codes 4, 5; z, w unused
    vec4 quad[4];     // clip-space corners of the proxy quad on the sprite plane (triangle strip)
};

// CONTRACT.md §5 cross-fade: ordered-dither threshold of a pixel (4x4 Bayer matrix, built from
// the bits of x^y and y), in (0, 1). A cross-fade at share f draws the new tier where the
// threshold is below f and the old tier elsewhere: complementary, stable from frame to frame.
VT_FN float vtDitherThreshold(ivec2 p) {
    int x = p.x & 3;
    int y = p.y & 3;
    int a = x ^ y;
    int v = ((a & 1) << 3) | ((y & 1) << 2) | ((a >> 1) << 1) | (y >> 1);
    return (float(v) + 0.5f) / 16.0f;
}

// Whether this tier draws the pixel of a sprite that is mid cross-fade (always, when not).
VT_FN bool vtDitherKeeps(VT_IN(SpriteGpu) s, vec2 pc) {
    if (!(s.fade > 0.0f)) return true;
    bool below = vtDitherThreshold(ivec2(int(floor(pc.x)), int(floor(pc.y)))) < s.fade;
    return s.fadeSide > 0.0f ? below : !below;
}

// §3.4-§3.5: pixel centre -> virtual-pixel cell (i, j) of the sprite lattice. The mapping is
// the exact eye-ray / sprite-plane intersection written as a ratio of two affine functions of
// the pixel centre. False when the pixel's ray misses the plane, meets it nearer than 2*zNear,
// or lands in a cell that cannot be drawn, and when a cross-fade gives the pixel to the other tier.
VT_FN bool vtPixelCell(VT_IN(SpriteGpu) s, vec2 pc, VT_OUT(ivec2) cell) {
    cell = ivec2(0, 0);
    if (!vtDitherKeeps(s, pc)) return false;
    VT_PRECISE float den = s.mapDen.x * pc.x + s.mapDen.y * pc.y + s.mapDen.z;
    if (!(den > 0.0f) || den > s.denMax) return false;
    VT_PRECISE float inv = 1.0f / den;
    VT_PRECISE float qi = (s.mapI.x * pc.x + s.mapI.y * pc.y + s.mapI.z) * inv;
    VT_PRECISE float qj = (s.mapJ.x * pc.x + s.mapJ.y * pc.y + s.mapJ.z) * inv;
    VT_PRECISE float fi = floor(qi);
    VT_PRECISE float fj = floor(qj);
    if (fi < float(s.cellRange.x) || fi > float(s.cellRange.y) || fj < float(s.cellRange.z) ||
        fj > float(s.cellRange.w))
        return false;
    cell = ivec2(int(fi), int(fj));
    return true;
}

// §3.6: origin of the primary ray of lattice cell (i, j), voxel space. The two cell offsets
// are summed before the base: a quarter-turn roll swaps (and negates) cellRight and cellUp,
// and this grouping keeps the origin bit-identical under it, so a far snapshot's rays equal
// the near rays at canonical views whatever the camera roll.
VT_FN vec3 vtCellRayOrigin(VT_IN(SpriteGpu) s, ivec2 cell) {
    VT_PRECISE vec3 o =
        s.rayBase + ((float(cell.x) + 0.5f) * s.cellRight + (float(cell.y) + 0.5f) * s.cellUp);
    return o;
}

// §3.7 lighting on 8-bit channels with 16.16 fixed-point factors: exact integer arithmetic, so
// no float-to-unorm conversion rule of any driver is involved.
VT_FN uint vtLit(uint rgba, uint factor) {
    uint r = min(255u, ((rgba & 255u) * factor + 32768u) >> 16);
    uint g = min(255u, (((rgba >> 8) & 255u) * factor + 32768u) >> 16);
    uint b = min(255u, (((rgba >> 16) & 255u) * factor + 32768u) >> 16);
    return r | (g << 8) | (b << 16) | (255u << 24);
}

VT_FN uint vtFaceLight(VT_IN(SpriteGpu) s, uint face) {
    return face < 4u ? s.faceLight0[int(face)] : s.faceLight1[int(face - 4u)];
}

// Cell-rate sprites (CONTRACT.md §3.11): what a pixel shows is a function of its lattice cell
// (§3.5) plus the per-pixel dither, depth and id, so a magnified sprite may trace each cell of
// its cellRange once and shade every pixel from that cell's outcome. The outcome is the far
// snapshot's payload packed in one uint: kind in bits 0-1, entered face in bits 2-4, palette
// index in bits 8-15. Cells are stored row by row over cellRange.
VT_FN uint vtPackOutcome(uint kind, uint index, uint face) {
    return kind | (face << 2) | (index << 8);
}
VT_FN uint vtUnpackOutcome(uint outcome, VT_OUT(uint) index, VT_OUT(uint) face) {
    index = (outcome >> 8) & 255u;
    face = (outcome >> 2) & 7u;
    return outcome & 3u;
}
VT_FN uint vtCellRowLength(VT_IN(SpriteGpu) s) {
    return uint(s.cellRange.y - s.cellRange.x + 1);
}
// Whether a cell lies in cellRange. Cells outside it cannot be non-empty, so their primary rays
// miss (core/sprite.cpp grows the projected model box by two cells: the outline ring and one
// cell of slack for float error).
VT_FN bool vtCellInRange(VT_IN(SpriteGpu) s, ivec2 cell) {
    return cell.x >= s.cellRange.x && cell.x <= s.cellRange.y && cell.y >= s.cellRange.z &&
           cell.y <= s.cellRange.w;
}
// §3.7 from stored primary outcomes: a cell's four neighbour rays are exactly the neighbours' own
// primary rays (vtShadeCell), so a cell-rate sprite traces only the primary ray of each cell and
// folds the outline in afterwards. Arguments: packed primary outcomes (vtPackOutcome, kind SOLID
// or EMPTY) of the cell and of its four cardinal neighbours (EMPTY outside cellRange). Returns
// what vtShadeCell returns for the cell, packed.
VT_FN uint vtOutcomeFromPrimaries(uint self, uint left, uint right, uint down, uint up) {
    if ((self & 3u) != VT_KIND_EMPTY) return self;
    if (((left | right | down | up) & 3u) != VT_KIND_EMPTY)
        return vtPackOutcome(VT_KIND_OUTLINE, 0u, 0u);
    return vtPackOutcome(VT_KIND_EMPTY, 0u, 0u);
}
// Index of a cell of cellRange in the row-by-row store, and back.
VT_FN uint vtCellSlot(VT_IN(SpriteGpu) s, ivec2 cell) {
    return uint(cell.y - s.cellRange.z) * vtCellRowLength(s) + uint(cell.x - s.cellRange.x);
}
VT_FN ivec2 vtSlotCell(VT_IN(SpriteGpu) s, uint slot) {
    uint w = vtCellRowLength(s);
    return ivec2(s.cellRange.x + int(slot % w), s.cellRange.z + int(slot / w));
}

// The voxel traversal of §3.6 (HARD_CASES DDA rules), in steps the near kernel (vtTrace below)
// and the far baker (impostor_cache/kernel_order_dda.hpp, which resumes it at an Embree bound)
// share, so the traversal exists once.
VT_FN ivec3 vtDims(VT_IN(SpriteGpu) s) {
    return ivec3(int(s.dims.x), int(s.dims.y), int(s.dims.z));
}

// Slab test of the ray (o, s.dir) against the model box; axis priority x < y < z on equal entry
// times (strict >). A point on a voxel boundary belongs to the voxel on its + side (floor), so
// the box is half-open [0, N) on axes the ray does not move along. False on a miss.
VT_FN bool vtSlabEntry(VT_IN(SpriteGpu) s, vec3 o, VT_OUT(float) tEnterOut,
                       VT_OUT(int) entryAxisOut) {
    tEnterOut = 0.0f;
    entryAxisOut = -1;
    ivec3 n = vtDims(s);
    VT_PRECISE float tEnter = -VT_FAR;
    VT_PRECISE float tExit = VT_FAR;
    int entryAxis = -1;
    for (int k = 0; k < 3; ++k) {
        if (s.dir[k] == 0.0f) {
            if (o[k] < 0.0f || !(o[k] < float(n[k]))) return false;
        } else {
            VT_PRECISE float t0 = (0.0f - o[k]) * s.invDir[k];
            VT_PRECISE float t1 = (float(n[k]) - o[k]) * s.invDir[k];
            VT_PRECISE float tNear = min(t0, t1);
            VT_PRECISE float tFar = max(t0, t1);
            if (tNear > tEnter) {
                tEnter = tNear;
                entryAxis = k;
            }
            tExit = min(tExit, tFar);
        }
    }
    if (!(tEnter < tExit) || entryAxis < 0) return false;
    tEnterOut = tEnter;
    entryAxisOut = entryAxis;
    return true;
}

// Entry cell: the entry axis is pinned to the face entered (HARD_CASES rule 3).
VT_FN ivec3 vtEntryCell(VT_IN(SpriteGpu) s, vec3 o, float tEnter, int entryAxis) {
    ivec3 n = vtDims(s);
    ivec3 c = ivec3(0, 0, 0);
    for (int k = 0; k < 3; ++k) {
        if (k == entryAxis) {
            c[k] = s.dir[k] > 0.0f ? 0 : n[k] - 1;
        } else {
            VT_PRECISE float p = o[k] + tEnter * s.dir[k];
            c[k] = clamp(int(floor(p)), 0, n[k] - 1);
        }
    }
    return c;
}

VT_FN ivec3 vtStepDir(VT_IN(SpriteGpu) s) {
    ivec3 d = ivec3(0, 0, 0);
    for (int k = 0; k < 3; ++k) d[k] = s.dir[k] > 0.0f ? 1 : (s.dir[k] < 0.0f ? -1 : 0);
    return d;
}

// Ray parameter of the voxel plane `plane` of axis k. Boundary crossings are recomputed from
// the integer plane each step (no accumulated error): a pure function of the plane.
VT_FN float vtPlaneT(VT_IN(SpriteGpu) s, vec3 o, int k, int plane) {
    VT_PRECISE float t = (float(plane) - o[k]) * s.invDir[k];
    return t;
}

// The next crossing of axis k out of cell c (VT_FAR on axes the ray does not move along).
VT_FN float vtNextCrossing(VT_IN(SpriteGpu) s, vec3 o, ivec3 c, ivec3 stepDir, int k) {
    return stepDir[k] != 0 ? vtPlaneT(s, o, k, c[k] + (stepDir[k] > 0 ? 1 : 0)) : VT_FAR;
}

// The axis the ray steps along next; ties step x before y before z.
VT_FN int vtStepAxis(float tx, float ty, float tz) {
    return (tx <= ty && tx <= tz) ? 0 : (ty <= tz ? 1 : 2);
}

// Code of the face entered along `axis`: 2*axis, +1 when the ray moves towards -axis.
VT_FN uint vtFaceCode(VT_IN(SpriteGpu) s, int axis) {
    return uint(2 * axis) + (s.dir[axis] > 0.0f ? 0u : 1u);
}

// The tracer needs a voxel source: in GLSL the including shader defines
// `uint vtFetchVoxel(ivec3 cell)`; in C++ it is a template parameter with `uint fetch(ivec3)`.
#ifdef __cplusplus
template <class Voxels> struct SpriteTracer {
    const Voxels& voxels;
#define VT_FETCH(c) voxels.fetch(c)
#else
#define VT_FETCH(c) vtFetchVoxel(c)
#endif

    // §3.6 + HARD_CASES DDA rules: the ray of cell (i, j) through the model's voxel AABB.
    // Returns true on the first voxel with palette index != 0, with the index and the code of
    // the face the ray entered it through (vtFaceCode). The steps are the traversal functions
    // above, which the far baker (impostor_cache/kernel_order_dda.hpp) calls too.
    VT_FN bool vtTrace(VT_IN(SpriteGpu) s, ivec2 cell, VT_OUT(uint) index, VT_OUT(uint) face) {
        index = 0u;
        face = 0u;
        VT_PRECISE vec3 o = vtCellRayOrigin(s, cell);
        float tEnter;
        int entryAxis;
        if (!vtSlabEntry(s, o, tEnter, entryAxis)) return false;
        ivec3 n = vtDims(s);
        ivec3 c = vtEntryCell(s, o, tEnter, entryAxis);
        ivec3 stepDir = vtStepDir(s);
        // Bound: a ray visits < nx+ny+nz cells.
        int axis = entryAxis;
        int maxSteps = n.x + n.y + n.z;
        for (int step = 0; step < maxSteps; ++step) {
            uint v = VT_FETCH(c);
            if (v != 0u) {
                index = v;
                face = vtFaceCode(s, axis);
                return true;
            }
            int a =
                vtStepAxis(vtNextCrossing(s, o, c, stepDir, 0), vtNextCrossing(s, o, c, stepDir, 1),
                           vtNextCrossing(s, o, c, stepDir, 2));
            c[a] += stepDir[a];
            if (c[a] < 0 || c[a] >= n[a]) return false;
            axis = a;
        }
        return false;
    }

    // §3.7: a hit is solid; otherwise any hit among the four cardinal neighbour cells makes an
    // outline pixel. Neighbour rays are exactly the neighbours' own primary rays, so the
    // outline equals a cardinal 2D dilation of the coverage mask (what the far tier bakes).
    VT_FN uint vtShadeCell(VT_IN(SpriteGpu) s, ivec2 cell, VT_OUT(uint) index, VT_OUT(uint) face) {
        if (vtTrace(s, cell, index, face)) return VT_KIND_SOLID;
        uint ni;
        uint nf;
        if (vtTrace(s, cell + ivec2(-1, 0), ni, nf) || vtTrace(s, cell + ivec2(1, 0), ni, nf) ||
            vtTrace(s, cell + ivec2(0, -1), ni, nf) || vtTrace(s, cell + ivec2(0, 1), ni, nf))
            return VT_KIND_OUTLINE;
        return VT_KIND_EMPTY;
    }

    // The packed primary outcome of one cell (SOLID with index and face, or EMPTY): what a
    // cell-rate sprite traces per cell before vtOutcomeFromPrimaries adds the outline.
    VT_FN uint vtTraceCellPrimary(VT_IN(SpriteGpu) s, ivec2 cell) {
        uint index;
        uint face;
        if (vtTrace(s, cell, index, face)) return vtPackOutcome(VT_KIND_SOLID, index, face);
        return vtPackOutcome(VT_KIND_EMPTY, 0u, 0u);
    }

    // One pixel of one sprite: VT_KIND_*, with palette index and face code when solid.
    VT_FN uint vtShadePixel(VT_IN(SpriteGpu) s, vec2 pc, VT_OUT(uint) index, VT_OUT(uint) face) {
        index = 0u;
        face = 0u;
        ivec2 cell;
        if (!vtPixelCell(s, pc, cell)) return VT_KIND_EMPTY;
        return vtShadeCell(s, cell, index, face);
    }

#ifdef __cplusplus
#undef VT_FETCH
};

static_assert(sizeof(SpriteGpu) == 272, "SpriteGpu must match the std430 layout in GLSL");
static_assert(offsetof(SpriteGpu, depth) == 12 && offsetof(SpriteGpu, denMax) == 28);
static_assert(offsetof(SpriteGpu, cellRange) == 128 && offsetof(SpriteGpu, dims) == 144);
static_assert(offsetof(SpriteGpu, atlas) == 160 && offsetof(SpriteGpu, faceLight1) == 192);
static_assert(offsetof(SpriteGpu, quad) == 208);
} // namespace voxtier::kernel
#endif

#endif // VOXTIER_SPRITE_KERNEL_H
