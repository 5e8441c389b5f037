#pragma once
// The near kernel's ray traversal (core/sprite_kernel.h vtTrace, made of the kernel's
// vtSlabEntry, vtEntryCell, vtPlaneT / vtNextCrossing, vtStepAxis and vtFaceCode, which this
// file calls rather than restates) with one addition: it can resume at a parameter tLow given
// from outside (the Embree lower bound), skipping the empty space before it without stepping
// through it, and still return exactly what vtTrace returns.
//
// Why this is exact. vtTrace recomputes each boundary crossing from the integer cell,
// t_k(P) = (float(P) - o_k) * invDir_k, a function of the plane P alone (not of the path), and
// strictly monotone along the ray. So the traversal is the merge of three sorted event lists,
// ordered by (t, axis) with x < y < z on ties, starting from the entry cell c0 (computed with
// the kernel's own slab test and floor). The state after "every event with t < tLow" is
// therefore one exact prefix of that merge, and counting each axis's events below tLow (a
// binary-free estimate plus a +-1 correction with the same float formula) lands on the very
// cell vtTrace would be in. Provided no solid voxel is visited before tLow — which is what the
// Embree pass guarantees, see snapshot_baker.cpp — continuing with the kernel's own step rule
// finds the kernel's hit, its palette index and its entered face, bit for bit.
#include "core/sprite_kernel.h"

#include <glm/glm.hpp>

#include <algorithm>
#include <cmath>
#include <cstdint>

namespace voxtier {

struct KernelOrderHit {
    bool hit = false;
    std::uint8_t index = 0;
    std::uint8_t face = 0; ///< kernel face code 0..5
    float t = 0.0f;        ///< ray parameter of the entered face (the event that entered the voxel)
    int steps = 0;         ///< voxel reads after the resume point (cost statistics)
    bool unresolved = false; ///< stopped after `maxReads` reads without an answer
};

/// The kernel's ray origin of lattice cell (i, j): the same float expression as vtTrace.
inline glm::vec3 kernelRayOrigin(const kernel::SpriteGpu& s, glm::ivec2 cell) {
    return kernel::vtCellRayOrigin(s, cell);
}

/// Where a ray stands after the kernel's slab test and its first voxel read.
struct KernelEntry {
    enum class Kind { Miss, Hit, Traverse } kind = Kind::Miss;
    glm::ivec3 cell{0}; ///< the entry cell c0 (Traverse, Hit)
    int axis = -1;      ///< the entry axis
    float tEnter = 0.0f;
    std::uint8_t index = 0; ///< Hit: palette index of c0
};

/// vtTrace's slab test, entry cell and first read: the kernel's own functions. `Voxels` provides
/// `unsigned fetch(glm::ivec3) const` (in-range cells only).
template <class Voxels>
KernelEntry kernelEntry(const kernel::SpriteGpu& s, glm::vec3 o, const Voxels& voxels) {
    KernelEntry e;
    float tEnter = 0.0f;
    int entryAxis = -1;
    if (!kernel::vtSlabEntry(s, o, tEnter, entryAxis)) return e;
    e.cell = kernel::vtEntryCell(s, o, tEnter, entryAxis);
    e.axis = entryAxis;
    e.tEnter = tEnter;
    const unsigned v = voxels.fetch(e.cell);
    e.kind = v != 0u ? KernelEntry::Kind::Hit : KernelEntry::Kind::Traverse;
    e.index = std::uint8_t(v);
    return e;
}

inline std::uint8_t kernelFaceCode(const kernel::SpriteGpu& s, int axis) {
    return std::uint8_t(kernel::vtFaceCode(s, axis));
}

/// Continues a Traverse entry. `haveBound == false` means "no solid voxel is visited after
/// the entry cell" (Embree found no candidate): a miss without reading anything. Otherwise the
/// traversal resumes at `tLow` (pass -VT_FAR for the plain kernel traversal). With `maxReads`,
/// it gives up after that many voxel reads and says so (`unresolved`).
template <class Voxels>
KernelOrderHit kernelResume(const kernel::SpriteGpu& s, glm::vec3 o, const Voxels& voxels,
                            const KernelEntry& e, bool haveBound, float tLow,
                            int maxReads = 1 << 30) {
    using kernel::VT_FAR;
    KernelOrderHit h;
    if (!haveBound) return h;
    const glm::ivec3 n = kernel::vtDims(s);
    glm::ivec3 c = e.cell;
    const glm::ivec3 step = kernel::vtStepDir(s);
    auto planeT = [&](int k, int plane) { return kernel::vtPlaneT(s, o, k, plane); };

    // Resume: count, per axis, the crossings with t < tLow (the events the kernel would have
    // processed by then, all through empty voxels).
    int axis = e.axis;
    float lastT = -VT_FAR;
    // A bound only a few crossings ahead is cheaper to walk to than to count exactly: the
    // plain traversal from c0 is the kernel's own and needs no bound at all.
    int estimate[3] = {0, 0, 0};
    int ahead = 0;
    if (tLow > -VT_FAR)
        for (int k = 0; k < 3; ++k) {
            if (step[k] == 0) continue;
            const int first = c[k] + (step[k] > 0 ? 1 : 0); // the next plane ahead of c0
            const float p = o[k] + tLow * s.dir[k];
            const float est = step[k] > 0 ? std::floor(p) - float(first) + 1.0f
                                          : float(first) - std::ceil(p) + 1.0f;
            estimate[k] = int(std::clamp(est, 0.0f, float(n[k] + 1)));
            ahead += estimate[k];
        }
    constexpr int kWalkInstead = 6;
    if (ahead > kWalkInstead) {
        for (int k = 0; k < 3; ++k) {
            if (step[k] == 0) continue;
            const int first = c[k] + (step[k] > 0 ? 1 : 0);
            // Correct the estimate with the kernel's own formula: m = #{planes with t < tLow}.
            int m = estimate[k];
            while (m > 0 && !(planeT(k, first + step[k] * (m - 1)) < tLow)) --m;
            while (m <= n[k] && planeT(k, first + step[k] * m) < tLow) ++m;
            if (m > 0) {
                const float tl = planeT(k, first + step[k] * (m - 1));
                if (tl >= lastT) { // lexicographic max of (t, axis): the later axis wins a tie
                    lastT = tl;
                    axis = k;
                }
                c[k] += step[k] * m;
                if (c[k] < 0 || c[k] >= n[k]) return h; // left the grid before tLow: a miss
            }
        }
    }
    float tCur = lastT;
    // vtTrace's loop from here on, same comparisons and tie order (x before y before z). The
    // entry cell was read by kernelEntry, so a cell is read here only after a step into it,
    // except when the resume moved the ray (then the resumed cell is read first).
    bool read = c != e.cell;
    // The next crossing per axis. planeT is a pure function of the plane, so keeping the two
    // axes that did not step instead of recomputing them gives the kernel's values exactly.
    float tn[3];
    for (int k = 0; k < 3; ++k) tn[k] = kernel::vtNextCrossing(s, o, c, step, k);
    const int maxSteps = n.x + n.y + n.z;
    for (int i = 0; i < maxSteps; ++i) {
        if (read) {
            if (h.steps >= maxReads) {
                h.unresolved = true;
                return h;
            }
            ++h.steps;
            if (const unsigned v = voxels.fetch(c); v != 0u)
                return {true, std::uint8_t(v), kernelFaceCode(s, axis), tCur, h.steps};
        }
        read = true;
        const int a = kernel::vtStepAxis(tn[0], tn[1], tn[2]);
        tCur = tn[a];
        c[a] += step[a];
        if (c[a] < 0 || c[a] >= n[a]) return h;
        tn[a] = kernel::vtNextCrossing(s, o, c, step, a);
        axis = a;
    }
    return h;
}

/// Both halves: exactly vtTrace's answer when no solid voxel is visited before `tLow`.
template <class Voxels>
KernelOrderHit traceKernelOrder(const kernel::SpriteGpu& s, glm::vec3 o, const Voxels& voxels,
                                bool haveBound, float tLow) {
    const KernelEntry e = kernelEntry(s, o, voxels);
    if (e.kind == KernelEntry::Kind::Miss) return {};
    if (e.kind == KernelEntry::Kind::Hit)
        return {true, e.index, kernelFaceCode(s, e.axis), e.tEnter, 1};
    KernelOrderHit h = kernelResume(s, o, voxels, e, haveBound, tLow);
    ++h.steps;
    return h;
}

} // namespace voxtier
