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
#define VT_INOUT(T) T&
#define VT_CONST inline constexpr
#define VT_FN inline
#else
#define VT_PRECISE precise
#define VT_IN(T) in T
#define VT_OUT(T) out T
#define VT_INOUT(T) inout T
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
    uint brickBase; // Vulkan: first word of this model frame's occupancy (vtFetchBrickWord)
    vec3 cellUp;    // sprite up / sigma (voxel space)
    uint skipEmpty; // 1: the ray marches over the frame's occupancy (vtMarchBoxes), 0: cell by cell
    vec3 dir;       // ray direction d (voxel space; components below 1e-6 are exactly 0)
    float reserved4;
    vec3 invDir; // 1/d per axis, 0 where d is 0
    float reserved5;
    ivec4 cellRange;  // iMin, iMax, jMin, jMax: every cell that can be non-empty, inclusive
    uvec4 dims;       // model size x, y, z; w = entity id
    uvec4 atlas;      // xyz: offset of this model frame in the voxel atlas; w: palette base
    uvec4 faceLight0; // 16.16 light factor per entered-face code 0..3
    uvec4 faceLight1; // face codes 4, 5; z, w unused
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
VT_FN float vtPlaneT1(float ok, float invDirK, int plane) {
    VT_PRECISE float t = (float(plane) - ok) * invDirK;
    return t;
}
VT_FN float vtPlaneT(VT_IN(SpriteGpu) s, vec3 o, int k, int plane) {
    return vtPlaneT1(o[k], s.invDir[k], plane);
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

// Empty-space skipping. Each model frame keeps a conservative two-level occupancy: bricks of
// VT_BRICK^3 voxels and regions of VT_REGION^3 voxels, cubes from the origin (the last of an axis
// cut at the model's size). A bit is set when its box may hold a non-empty voxel and clear only
// when all of the box's voxels are empty (core/voxel_model.hpp BrickOccupancy keeps it so through
// edits). Each level numbers its boxes x fastest over vtLevelDims, 32 to a uint word, box i in
// word i >> 5 at bit i & 31; the brick words come first, then the region words.
VT_CONST int VT_BRICK_SHIFT = 2;
VT_CONST int VT_REGION_SHIFT = 4;
VT_CONST int VT_BRICK = 1 << VT_BRICK_SHIFT;
VT_CONST int VT_REGION = 1 << VT_REGION_SHIFT;
VT_FN ivec3 vtLevelDims(ivec3 n, int shift) {
    return (n + ivec3((1 << shift) - 1)) >> shift;
}
VT_FN uint vtLevelIndex(ivec3 levelDims, ivec3 box) {
    return uint(box.x + levelDims.x * (box.y + levelDims.y * box.z));
}
// Words of the brick level: the region level's first word.
VT_FN uint vtBrickWords(ivec3 n) {
    ivec3 d = vtLevelDims(n, VT_BRICK_SHIFT);
    return (uint(d.x * d.y * d.z) + 31u) >> 5;
}

// The exit plane, along an axis with step stepK, of the box of side 1 << shift that holds cell
// coordinate ck (the box is cut at the model's size nk).
VT_FN int vtBoxPlane(int ck, int stepK, int nk, int shift) {
    int lo = (ck >> shift) << shift;
    return stepK > 0 ? min(lo + (1 << shift), nk) : lo;
}

// Empty-space skipping crosses an empty box (a brick or a region) in one step, and exactly. Why
// exact: the cell-by-cell march (vtMarchCells) takes boundary crossings from three per-axis
// sequences of planes, each crossing's t a pure function of its plane (vtPlaneT) and monotone
// along the axis, and always steps the least (t, axis), x < y < z on ties (vtStepAxis): it visits
// the merge of the three sequences ordered by (t, axis). Restricted to the planes of boxes of one
// size (a subsequence of each axis's planes), that merge is the same rule applied to box planes:
// vtBoxStep, which moves the box coordinates exactly while the cells it passes are empty (so their
// reads change nothing). The cell along the step's axis is then known (the first of the new box);
// along another axis k the march has crossed exactly the planes whose (t, k) precedes the step's
// (tLast, axis): t < tLast, or t == tLast with k < axis. vtSettle counts those (vtSettleAxis)
// when the march next needs its cell.

// One box step: from the box of side 1 << shift holding c (c exact down to that side) across the
// box plane the merge takes first. Sets that axis's cell to the new box's first, `axis` and
// `tLast` to the step, and returns false when the step leaves the grid (the march's miss).
VT_FN bool vtBoxStep(VT_IN(SpriteGpu) s, vec3 o, ivec3 stepDir, int shift, VT_INOUT(ivec3) c,
                     VT_INOUT(int) axis, VT_OUT(float) tLast) {
    ivec3 n = vtDims(s);
    ivec3 plane =
        ivec3(vtBoxPlane(c.x, stepDir.x, n.x, shift), vtBoxPlane(c.y, stepDir.y, n.y, shift),
              vtBoxPlane(c.z, stepDir.z, n.z, shift));
    VT_PRECISE float tx = stepDir.x != 0 ? vtPlaneT1(o.x, s.invDir.x, plane.x) : VT_FAR;
    VT_PRECISE float ty = stepDir.y != 0 ? vtPlaneT1(o.y, s.invDir.y, plane.y) : VT_FAR;
    VT_PRECISE float tz = stepDir.z != 0 ? vtPlaneT1(o.z, s.invDir.z, plane.z) : VT_FAR;
    int a = vtStepAxis(tx, ty, tz);
    tLast = a == 0 ? tx : (a == 1 ? ty : tz);
    axis = a;
    // The new box's first cell along a: the plane itself going up, the cell below it going down.
    int first =
        a == 0 ? plane.x - (stepDir.x < 0 ? 1 : 0)
               : (a == 1 ? plane.y - (stepDir.y < 0 ? 1 : 0) : plane.z - (stepDir.z < 0 ? 1 : 0));
    c = ivec3(a == 0 ? first : c.x, a == 1 ? first : c.y, a == 2 ? first : c.z);
    return first >= 0 && first < (a == 0 ? n.x : (a == 1 ? n.y : n.z));
}

// vtSettle along one axis k other than the last step's: ck is the axis's last settled cell (the
// march never moves back), in the same box of side 1 << shift as the march's cell now, whose exit
// plane is `plane`. The planes from ck's next to the box plane (which follows (tLast, axis): the
// box coordinate is exact) are crossed while their (t, k) precedes (tLast, axis); the position at
// tLast guesses how many, and the comparisons alone decide. Scalars only, so that no vector is
// indexed by a variable.
VT_FN int vtSettleAxis(float ok, float dirK, float invDirK, int k, int stepK, int ck, int plane,
                       float tLast, int axis) {
    if (stepK == 0 || k == axis) return ck;
    int first = ck + (stepK > 0 ? 1 : 0);
    int planes = (plane - first) * stepK;
    int at = int(clamp(ok + tLast * dirK, -1.0f, float(max(plane, ck) + 1)));
    int m = clamp(stepK > 0 ? at - ck : ck - at, 0, planes);
    for (; m > 0; --m) {
        VT_PRECISE float t = vtPlaneT1(ok, invDirK, first + stepK * (m - 1));
        if (t < tLast || (t == tLast && k < axis)) break;
    }
    for (; m < planes; ++m) {
        VT_PRECISE float t = vtPlaneT1(ok, invDirK, first + stepK * m);
        if (!(t < tLast || (t == tLast && k < axis))) break;
    }
    return ck + stepK * m;
}

// The march's cell after box steps: exact along the last step's axis, and exact down to boxes of
// side 1 << shift along the others; settled along those to the cell (vtSettleAxis).
VT_FN ivec3 vtSettle(VT_IN(SpriteGpu) s, vec3 o, ivec3 stepDir, int shift, ivec3 c, float tLast,
                     int axis) {
    ivec3 n = vtDims(s);
    return ivec3(vtSettleAxis(o.x, s.dir.x, s.invDir.x, 0, stepDir.x, c.x,
                              vtBoxPlane(c.x, stepDir.x, n.x, shift), tLast, axis),
                 vtSettleAxis(o.y, s.dir.y, s.invDir.y, 1, stepDir.y, c.y,
                              vtBoxPlane(c.y, stepDir.y, n.y, shift), tLast, axis),
                 vtSettleAxis(o.z, s.dir.z, s.invDir.z, 2, stepDir.z, c.z,
                              vtBoxPlane(c.z, stepDir.z, n.z, shift), tLast, axis));
}

// The tracer needs a voxel source: in GLSL the including shader defines
// `uint vtFetchVoxel(ivec3 cell)` and `uint vtFetchBrickWord(uint word)` (word `word` of the
// frame's occupancy); in C++ it is a template parameter with `uint fetch(ivec3)` and optionally
// `uint fetchBrickWord(uint)` (without it every box counts as occupied: the plain cell-by-cell
// traversal, which the far baker's sources and the tests' probes use).
#ifdef __cplusplus
template <class Voxels> inline constexpr bool vtHasOccupancy = requires(const Voxels& v, uint w) {
    v.fetchBrickWord(w);
};
template <class Voxels> inline uint vtBrickWordOf(const Voxels& voxels, uint word) {
    if constexpr (vtHasOccupancy<Voxels>)
        return voxels.fetchBrickWord(word);
    else
        return 0xFFFFFFFFu;
}
template <class Voxels> struct SpriteTracer {
    const Voxels& voxels;
#define VT_FETCH(c) voxels.fetch(c)
#define VT_FETCH_BRICK_WORD(w) vtBrickWordOf(voxels, w)
#else
uint vtFetchVoxel(ivec3 cell);
uint vtFetchBrickWord(uint word);
#define VT_FETCH(c) vtFetchVoxel(c)
#define VT_FETCH_BRICK_WORD(w) vtFetchBrickWord(w)
#endif

    // Whether box `box` of a level (its dims, its first word) may hold a non-empty voxel: one
    // read of the occupancy.
    VT_FN bool vtBoxOccupied(ivec3 levelDims, uint base, ivec3 box) {
        uint i = vtLevelIndex(levelDims, box);
        return ((VT_FETCH_BRICK_WORD(base + (i >> 5u)) >> (i & 31u)) & 1u) != 0u;
    }

    // The cell-by-cell march of vtTrace from cell c, entered along `axis`: every cell read.
    VT_FN bool vtMarchCells(VT_IN(SpriteGpu) s, vec3 o, ivec3 c, int axis, VT_OUT(uint) index,
                            VT_OUT(uint) face) {
        ivec3 n = vtDims(s);
        ivec3 stepDir = vtStepDir(s);
        // Bound: a ray visits < nx+ny+nz cells.
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

    // The same march over the occupancy: regions and bricks marked empty are crossed in one box
    // step each (vtBoxStep), which changes no outcome; only the cells of occupied bricks are read.
    VT_FN bool vtMarchBoxes(VT_IN(SpriteGpu) s, vec3 o, ivec3 c, int axis, VT_OUT(uint) index,
                            VT_OUT(uint) face) {
        ivec3 n = vtDims(s);
        ivec3 stepDir = vtStepDir(s);
        ivec3 brickDims = vtLevelDims(n, VT_BRICK_SHIFT);
        ivec3 regionDims = vtLevelDims(n, VT_REGION_SHIFT);
        uint regionBase = vtBrickWords(n);
        // What to test next: 2 the region, then the brick; 1 the brick.
        int level = 2;
        // c is exact down to boxes of side 1 << exactShift (0: the march's cell); the step
        // (tLast, axis) settles it (vtSettle) when a cell is next needed.
        int exactShift = 0;
        float tLast = 0.0f;
        // Bound: a ray visits < nx+ny+nz cells, and every step (of a cell or a box) moves it on
        // by at least one of them.
        int maxSteps = n.x + n.y + n.z;
        int steps = 0;
        while (steps < maxSteps) {
            if (level == 2) {
                if (!vtBoxOccupied(regionDims, regionBase, c >> VT_REGION_SHIFT)) {
                    if (!vtBoxStep(s, o, stepDir, VT_REGION_SHIFT, c, axis, tLast)) return false;
                    exactShift = VT_REGION_SHIFT;
                    ++steps;
                    continue;
                }
                if (exactShift > VT_BRICK_SHIFT) {
                    c = vtSettle(s, o, stepDir, exactShift, c, tLast, axis);
                    exactShift = 0;
                }
            }
            if (!vtBoxOccupied(brickDims, 0u, c >> VT_BRICK_SHIFT)) {
                if (!vtBoxStep(s, o, stepDir, VT_BRICK_SHIFT, c, axis, tLast)) return false;
                exactShift = VT_BRICK_SHIFT;
                ++steps;
                // A new region too when the new brick is the region's first along the step.
                level = ((c[axis] ^ (c[axis] - stepDir[axis])) >> VT_REGION_SHIFT) != 0 ? 2 : 1;
                continue;
            }
            if (exactShift > 0) {
                c = vtSettle(s, o, stepDir, exactShift, c, tLast, axis);
                exactShift = 0;
            }
            // The cells of this occupied brick, cell by cell, until a step reaches `beyond` (the
            // first cell past the brick along its axis), which stands in for the grid's bounds.
            ivec3 lo = (c >> VT_BRICK_SHIFT) << VT_BRICK_SHIFT;
            ivec3 beyond = ivec3(stepDir.x > 0 ? min(lo.x + VT_BRICK, n.x) : lo.x - 1,
                                 stepDir.y > 0 ? min(lo.y + VT_BRICK, n.y) : lo.y - 1,
                                 stepDir.z > 0 ? min(lo.z + VT_BRICK, n.z) : lo.z - 1);
            for (; steps < maxSteps; ++steps) {
                uint v = VT_FETCH(c);
                if (v != 0u) {
                    index = v;
                    face = vtFaceCode(s, axis);
                    return true;
                }
                int a = vtStepAxis(vtNextCrossing(s, o, c, stepDir, 0),
                                   vtNextCrossing(s, o, c, stepDir, 1),
                                   vtNextCrossing(s, o, c, stepDir, 2));
                c[a] += stepDir[a];
                axis = a;
                if (c[a] == beyond[a]) break;
            }
            if (c[axis] < 0 || c[axis] >= n[axis]) return false;
            ++steps;
            level = ((c[axis] ^ (c[axis] - stepDir[axis])) >> VT_REGION_SHIFT) != 0 ? 2 : 1;
        }
        return false;
    }

    // §3.6 + HARD_CASES DDA rules: the ray of cell (i, j) through the model's voxel AABB.
    // Returns true on the first voxel with palette index != 0, with the index and the code of
    // the face the ray entered it through (vtFaceCode). The steps are the traversal functions
    // above, which the far baker (impostor_cache/kernel_order_dda.hpp) calls too. Sprites whose
    // frame has empty space worth skipping (SpriteGpu::skipEmpty) march over its occupancy, the
    // others cell by cell; both give the same outcome.
    VT_FN bool vtTrace(VT_IN(SpriteGpu) s, ivec2 cell, VT_OUT(uint) index, VT_OUT(uint) face) {
        index = 0u;
        face = 0u;
        VT_PRECISE vec3 o = vtCellRayOrigin(s, cell);
        float tEnter;
        int entryAxis;
        if (!vtSlabEntry(s, o, tEnter, entryAxis)) return false;
        ivec3 c = vtEntryCell(s, o, tEnter, entryAxis);
#ifdef __cplusplus
        if constexpr (!vtHasOccupancy<Voxels>) return vtMarchCells(s, o, c, entryAxis, index, face);
#endif
            // GLSL holds the march only where compiled with VT_SKIP_EMPTY (NearOptions::skipEmpty):
            // on llvmpipe the shader's size alone cost 1.3-2x, skipping or not.
#if defined(__cplusplus) || defined(VT_SKIP_EMPTY)
        if (s.skipEmpty != 0u) return vtMarchBoxes(s, o, c, entryAxis, index, face);
#endif
        return vtMarchCells(s, o, c, entryAxis, index, face);
    }

    // §3.7: a hit is solid; otherwise any hit among the four cardinal neighbour cells makes an
    // outline pixel. Neighbour rays are exactly the neighbours' own primary rays, so the
    // outline equals a cardinal 2D dilation of the coverage mask (what the far tier bakes).
    // index and face are 0 unless solid: a GLSL `out` parameter is not copied in, so after a
    // miss (which assigns neither) vtTrace's would be undefined on a GPU, where C++ references
    // keep 0, and a packed outcome would carry the garbage.
    VT_FN uint vtShadeCell(VT_IN(SpriteGpu) s, ivec2 cell, VT_OUT(uint) index, VT_OUT(uint) face) {
        if (vtTrace(s, cell, index, face)) return VT_KIND_SOLID;
        index = 0u;
        face = 0u;
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
#undef VT_FETCH_BRICK_WORD
};

static_assert(sizeof(SpriteGpu) == 208, "SpriteGpu must match the std430 layout in GLSL");
static_assert(offsetof(SpriteGpu, depth) == 12 && offsetof(SpriteGpu, denMax) == 28);
static_assert(offsetof(SpriteGpu, brickBase) == 76 && offsetof(SpriteGpu, skipEmpty) == 92);
static_assert(offsetof(SpriteGpu, cellRange) == 128 && offsetof(SpriteGpu, dims) == 144);
static_assert(offsetof(SpriteGpu, atlas) == 160 && offsetof(SpriteGpu, faceLight1) == 192);
} // namespace voxtier::kernel
#endif

#endif // VOXTIER_SPRITE_KERNEL_H
