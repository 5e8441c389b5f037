// setupSpriteInto for many sprites at once (CONTRACT.md §3.1-§3.10): the scalar set-up of
// sprite.cpp on N entities per instruction (N = 2 on SSE4, 4 on AVX2, 8 on AVX-512), compiled for
// every SIMD target Highway knows and dispatched to the best one the CPU has at run time.
//
// Why: with a moving camera every sprite is set up again each frame, and the scalar set-up is one
// long chain of square roots and divisions per sprite (its lattice alone normalises five vectors
// in a row), which a core cannot overlap with the next sprite's. Lanes of independent sprites run
// those chains side by side.
//
// It writes the same bits as the scalar set-up because every lane performs that code's IEEE
// operations in its order: glm's dot ((x + y) + z), normalize (v * (1 / sqrt(dot))), cross and
// matrix products as glm spells them, divisions where it divides (never a reciprocal it does
// not take); the project builds with -ffp-contract=off, so nothing is fused. Branches become
// selects computed on every lane, and the float fields' rounding (toGpuFloat) is the lanes'
// round-to-nearest demotion with the same flush of subnormals. What stays per sprite, in scalar
// code after the vectors, is the culling tests in their order, the int conversions and the
// rectangle's clamp (tests/sprite_setup_simd_test.cpp compares every field, bit for bit).
#undef HWY_TARGET_INCLUDE
#define HWY_TARGET_INCLUDE "core/sprite_setup_simd.cpp"
#include "core/sprite.hpp"

#include <hwy/foreach_target.h> // IWYU pragma: keep
#include <hwy/highway.h>

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <new>

HWY_BEFORE_NAMESPACE();
namespace voxtier::sprite_setup_simd {
namespace HWY_NAMESPACE {
namespace hn = hwy::HWY_NAMESPACE;

#if HWY_HAVE_FLOAT64 && HWY_TARGET != HWY_SCALAR
using D = hn::ScalableTag<double>;
using V = hn::Vec<D>;

struct V3 {
    V x, y, z;
};

HWY_INLINE V3 add(const V3& a, const V3& b) {
    return {hn::Add(a.x, b.x), hn::Add(a.y, b.y), hn::Add(a.z, b.z)};
}
HWY_INLINE V3 sub(const V3& a, const V3& b) {
    return {hn::Sub(a.x, b.x), hn::Sub(a.y, b.y), hn::Sub(a.z, b.z)};
}
HWY_INLINE V3 scale(V s, const V3& a) {
    return {hn::Mul(s, a.x), hn::Mul(s, a.y), hn::Mul(s, a.z)};
}
HWY_INLINE V3 divide(const V3& a, V s) {
    return {hn::Div(a.x, s), hn::Div(a.y, s), hn::Div(a.z, s)};
}
HWY_INLINE V dot(const V3& a, const V3& b) {
    return hn::Add(hn::Add(hn::Mul(a.x, b.x), hn::Mul(a.y, b.y)), hn::Mul(a.z, b.z));
}
HWY_INLINE V length(const V3& a) {
    return hn::Sqrt(dot(a, a));
}
HWY_INLINE V3 normalize(const V3& a) {
    return scale(hn::Div(hn::Set(D(), 1.0), length(a)), a);
}
HWY_INLINE V3 cross(const V3& a, const V3& b) {
    return {hn::Sub(hn::Mul(a.y, b.z), hn::Mul(b.y, a.z)),
            hn::Sub(hn::Mul(a.z, b.x), hn::Mul(b.z, a.x)),
            hn::Sub(hn::Mul(a.x, b.y), hn::Mul(b.x, a.y))};
}
/// snapComponents: components below kDirectionSnap in magnitude set to 0.
HWY_INLINE V snap(V v) {
    return hn::IfThenZeroElse(hn::Lt(hn::Abs(v), hn::Set(D(), kDirectionSnap)), v);
}
HWY_INLINE V3 snap(const V3& a) {
    return {snap(a.x), snap(a.y), snap(a.z)};
}
HWY_INLINE V3 splat(glm::dvec3 v) {
    const D d;
    return {hn::Set(d, v.x), hn::Set(d, v.y), hn::Set(d, v.z)};
}

/// A dmat3 per lane, by column: m[c][r] as glm indexes it.
struct M3 {
    V m[3][3];
    /// glm's m * v: row r is (m[0][r] v.x + m[1][r] v.y) + m[2][r] v.z.
    V3 times(const V3& v) const {
        V r[3];
        for (int i = 0; i < 3; ++i)
            r[i] = hn::Add(hn::Add(hn::Mul(m[0][i], v.x), hn::Mul(m[1][i], v.y)),
                           hn::Mul(m[2][i], v.z));
        return {r[0], r[1], r[2]};
    }
    /// glm's transpose(m) * v: row r is (m[r][0] v.x + m[r][1] v.y) + m[r][2] v.z.
    V3 transposedTimes(const V3& v) const {
        V r[3];
        for (int i = 0; i < 3; ++i)
            r[i] = hn::Add(hn::Add(hn::Mul(m[i][0], v.x), hn::Mul(m[i][1], v.y)),
                           hn::Mul(m[i][2], v.z));
        return {r[0], r[1], r[2]};
    }
};

/// Every per-lane double the scalar tail reads, by field.
enum Out : int {
    kCentreRel, // 3
    kViewDepth = kCentreRel + 3,
    kDistance,
    kRadiusPx,
    kEyeVoxel, // 3
    kDir = kEyeVoxel + 3,
    kUp = kDir + 3,
    kRight = kUp + 3,
    kGU = kRight + 3,
    kGV,
    kCellRange,           // 4 floors
    kLo = kCellRange + 4, // 2
    kHi = kLo + 2,        // 2
    kCellSizePx = kHi + 2,
    kLineOfSight, // 3
    kSigmaDepth = kLineOfSight + 3,
    kOutCount,
};
/// What the scalar tail copies as floats (toGpuFloat, on the lanes), by field.
enum OutFloat : int {
    kFMapI,                // 3
    kFMapJ = kFMapI + 3,   // 3
    kFMapDen = kFMapJ + 3, // 3
    kFDenMax = kFMapDen + 3,
    kFDepth,
    kFRayBase,                   // 3
    kFCellRight = kFRayBase + 3, // 3
    kFCellUp = kFCellRight + 3,  // 3
    kFDir = kFCellUp + 3,        // 3
    kFInvDir = kFDir + 3,        // 3
    kFQuad = kFInvDir + 3,       // 4 corners x (x, y, w)
    kFloatCount = kFQuad + 12,
};
/// The inputs per lane: the pose (rotation by column, position, anchor, metres per voxel), the
/// model frame's size and its largest side.
enum In : int {
    kRotation,                 // 9, m[c][r] at 3c + r
    kPosition = kRotation + 9, // 3
    kAnchor = kPosition + 3,   // 3
    kMetresPerVoxel = kAnchor + 3,
    kDims, // 3
    kMaxDim = kDims + 3,
    kInCount,
};

/// toGpuFloat of sprite.cpp: float rounding with subnormals flushed to 0.
float toGpuFloat(double v) {
    const float f = static_cast<float>(v);
    return std::abs(f) < 1.17549435e-38f ? 0.0f : f;
}

/// The lanes' set-up, as far as it is vector arithmetic: writes out[field * N + lane] and the
/// float fields outFloat[field * N + lane].
void SetupLanes(const CameraFrame& cam, const RenderParams& params, const double* in, double* out,
                float* outFloat) {
    const D d;
    const std::size_t N = hn::Lanes(d);
    const auto load = [&](int field) { return hn::Load(d, in + std::size_t(field) * N); };
    const auto load3 = [&](int field) -> V3 {
        return {load(field), load(field + 1), load(field + 2)};
    };
    const auto store = [&](V v, int field) { hn::Store(v, d, out + std::size_t(field) * N); };
    const auto store3 = [&](const V3& v, int field) {
        store(v.x, field), store(v.y, field + 1), store(v.z, field + 2);
    };
    // toGpuFloat: rounded to float, subnormals flushed to 0.
    const hn::Rebind<float, D> df;
    const auto storeFloat = [&](V v, int field) {
        const auto f = hn::DemoteTo(df, v);
        hn::Store(hn::IfThenZeroElse(hn::Lt(hn::Abs(f), hn::Set(df, 1.17549435e-38f)), f), df,
                  outFloat + std::size_t(field) * N);
    };
    const auto storeFloat3 = [&](const V3& v, int field) {
        storeFloat(v.x, field), storeFloat(v.y, field + 1), storeFloat(v.z, field + 2);
    };
    const V zero = hn::Zero(d), one = hn::Set(d, 1.0);
    M3 R;
    for (int c = 0; c < 3; ++c)
        for (int r = 0; r < 3; ++r) R.m[c][r] = load(kRotation + 3 * c + r);
    const V3 position = load3(kPosition), anchor = load3(kAnchor);
    const V k = load(kMetresPerVoxel);
    const V3 dims = load3(kDims);
    const V sigma = hn::Set(d, params.sigma);
    const V zNear = hn::Set(d, cam.zNear);
    const V3 eye = splat(cam.eye), forward = splat(cam.forward);
    const V3 camRight = splat(cam.right), camUp = splat(cam.up);

    // §3.1: pose.relativeWorld(c, eye) = (position - eye) + R ((c - anchor) k).
    const V3 c = scale(hn::Set(d, 0.5), dims); // glm: dvec3(dims) * 0.5
    const V3 offset = sub(position, eye);
    const V3 centreRel = add(offset, R.times(scale(k, sub(c, anchor))));
    const V viewDepth = dot(centreRel, forward);
    const V distance = length(centreRel);
    // (length(c) k / viewDepth) focalPx, or 0 behind the eye.
    const V radius = hn::Mul(hn::Div(hn::Mul(length(c), k), viewDepth), hn::Set(d, cam.focalPx()));
    const V radiusPx = hn::IfThenElseZero(hn::Gt(viewDepth, zero), radius);
    store3(centreRel, kCentreRel);
    store(viewDepth, kViewDepth);
    store(distance, kDistance);
    store(radiusPx, kRadiusPx);
    // §3.9: anchor + voxelDirection(-(position - eye)) / k.
    const V3 toEye = {hn::Neg(offset.x), hn::Neg(offset.y), hn::Neg(offset.z)};
    store3(add(anchor, divide(R.transposedTimes(toEye), k)), kEyeVoxel);

    // §3.2-§3.3: the lattice (makeSpriteLattice) of the voxel-space view direction.
    const V3 dirWorld =
        params.viewMode == ViewMode::PerEntity ? divide(centreRel, distance) : forward;
    const V3 dirHint = R.transposedTimes(dirWorld);
    const V3 upHint = R.transposedTimes(camUp);
    const V3 fallbackUp = R.transposedTimes(forward);
    const V3 dir = normalize(snap(normalize(dirHint)));
    const V3 upFromHint = sub(upHint, scale(dot(upHint, dir), dir));
    const V3 upFromFallback = sub(fallbackUp, scale(dot(fallbackUp, dir), dir));
    // std::max(1.0, length(upHint)) is (1 < x ? x : 1).
    const V hintLength = length(upHint);
    const V bound =
        hn::Mul(hn::Set(d, 1e-6), hn::IfThenElse(hn::Lt(one, hintLength), hintLength, one));
    const auto useFallback = hn::Lt(length(upFromHint), bound);
    const V3 upRaw = {hn::IfThenElse(useFallback, upFromFallback.x, upFromHint.x),
                      hn::IfThenElse(useFallback, upFromFallback.y, upFromHint.y),
                      hn::IfThenElse(useFallback, upFromFallback.z, upFromHint.z)};
    const V3 up = normalize(snap(normalize(upRaw)));
    const V3 right = normalize(snap(cross(dir, up)));
    const V3 g = sub({hn::Floor(c.x), hn::Floor(c.y), hn::Floor(c.z)}, c);
    const V gU = dot(g, right), gV = dot(g, up);
    const auto extent = [&](const V3& axis) {
        return hn::Add(hn::Add(hn::Mul(c.x, hn::Abs(axis.x)), hn::Mul(c.y, hn::Abs(axis.y))),
                       hn::Mul(c.z, hn::Abs(axis.z)));
    };
    const V eu = extent(right), ev = extent(up);
    const V iMin = hn::Floor(hn::Mul(sigma, hn::Sub(hn::Neg(eu), gU)));
    const V iMax = hn::Floor(hn::Mul(sigma, hn::Sub(eu, gU)));
    const V jMin = hn::Floor(hn::Mul(sigma, hn::Sub(hn::Neg(ev), gV)));
    const V jMax = hn::Floor(hn::Mul(sigma, hn::Sub(ev, gV)));
    store3(dir, kDir);
    store3(up, kUp);
    store3(right, kRight);
    store(gU, kGU);
    store(gV, kGV);
    store(iMin, kCellRange), store(iMax, kCellRange + 1);
    store(jMin, kCellRange + 2), store(jMax, kCellRange + 3);
    // The selection inputs (selectionInputs of sprite.cpp): cellSizePx, the radius over the
    // radius in cells; the displacement predictor's line of sight, -normalize(-dir), which is
    // dir * (1 / length(dir)) to the bit (negation is exact), and sigma times the box's half depth
    // along it.
    const V radiusCells = hn::Mul(length(c), sigma);
    store(hn::IfThenElseZero(hn::Gt(radiusCells, zero), hn::Div(radiusPx, radiusCells)),
          kCellSizePx);
    const V3 lineOfSight = normalize(dir);
    store3(lineOfSight, kLineOfSight);
    const V3 losAbs = {hn::Abs(lineOfSight.x), hn::Abs(lineOfSight.y), hn::Abs(lineOfSight.z)};
    store(hn::Mul(sigma, dot(c, losAbs)), kSigmaDepth);

    // §3.4: the screen -> sprite mapping (the plane's basis back in world space).
    const V3 dW = R.times(dir), rW = R.times(right), uW = R.times(up);
    const V Cd = dot(centreRel, dW), Cr = dot(centreRel, rW), Cu = dot(centreRel, uW);
    const V pixelScale = hn::Set(d, cam.pixelScale());
    const V halfWidth = hn::Set(d, 0.5 * cam.width), halfHeight = hn::Set(d, 0.5 * cam.height);
    const auto screenLinear = [&](const V3& a) -> V3 {
        const V ra = hn::Mul(pixelScale, dot(camRight, a));
        const V ua = hn::Mul(pixelScale, dot(camUp, a));
        return {ra, hn::Neg(ua),
                hn::Add(hn::Sub(dot(forward, a), hn::Mul(halfWidth, ra)), hn::Mul(halfHeight, ua))};
    };
    const V3 den = screenLinear(dW);
    const V sk = hn::Div(sigma, k);
    const V3 numI = sub(scale(sk, sub(scale(Cd, screenLinear(rW)), scale(Cr, den))),
                        scale(hn::Mul(sigma, gU), den));
    const V3 numJ = sub(scale(sk, sub(scale(Cd, screenLinear(uW)), scale(Cu, den))),
                        scale(hn::Mul(sigma, gV), den));
    storeFloat3(numI, kFMapI);
    storeFloat3(numJ, kFMapJ);
    storeFloat3(den, kFMapDen);
    storeFloat(hn::Div(Cd, hn::Set(d, 2.0 * cam.zNear)), kFDenMax);
    storeFloat(hn::Div(zNear, viewDepth), kFDepth);
    const V twiceMax = hn::Mul(hn::Set(d, 2.0), load(kMaxDim));
    storeFloat3(sub(add(add(c, scale(gU, right)), scale(gV, up)), scale(twiceMax, dir)), kFRayBase);
    storeFloat3(divide(right, sigma), kFCellRight);
    storeFloat3(divide(up, sigma), kFCellUp);
    storeFloat3(dir, kFDir);
    const auto inverse = [&](V v) { return hn::IfThenElseZero(hn::Ne(v, zero), hn::Div(one, v)); };
    storeFloat3({inverse(dir.x), inverse(dir.y), inverse(dir.z)}, kFInvDir);

    // §3.10: the proxy quad, in clip space, and the screen rectangle of its part beyond zNear.
    const V marginVox = hn::Add(hn::Div(one, sigma),
                                hn::Div(hn::Mul(hn::Set(d, 2.0 * cam.pixelScale()), viewDepth), k));
    // cellRange as ints is floor - 2 (min) or floor + 2 (max); (cellRange.x - 1) / sigma etc.
    const V u0 = hn::Sub(hn::Add(gU, hn::Div(hn::Sub(iMin, hn::Set(d, 3.0)), sigma)), marginVox);
    const V u1 = hn::Add(hn::Add(gU, hn::Div(hn::Add(iMax, hn::Set(d, 4.0)), sigma)), marginVox);
    const V v0 = hn::Sub(hn::Add(gV, hn::Div(hn::Sub(jMin, hn::Set(d, 3.0)), sigma)), marginVox);
    const V v1 = hn::Add(hn::Add(gV, hn::Div(hn::Add(jMax, hn::Set(d, 4.0)), sigma)), marginVox);
    const V cu[4] = {u0, u1, u0, u1}, cv[4] = {v0, v0, v1, v1}; // triangle strip
    const double aspect = double(cam.width) / double(cam.height);
    const V clipX = hn::Set(d, cam.tanHalfFovY * aspect), clipY = hn::Set(d, cam.tanHalfFovY);
    V qx[4], qy[4], qw[4];
    for (int i = 0; i < 4; ++i) {
        const V3 P = add(centreRel, scale(k, add(scale(cu[i], rW), scale(cv[i], uW))));
        // clipFromCameraRelative: (v.x / (tan aspect), -v.y / tan, zNear, v.z).
        qx[i] = hn::Div(dot(P, camRight), clipX);
        qy[i] = hn::Div(hn::Neg(dot(P, camUp)), clipY);
        qw[i] = dot(P, forward);
        storeFloat(qx[i], kFQuad + 3 * i), storeFloat(qy[i], kFQuad + 3 * i + 1);
        storeFloat(qw[i], kFQuad + 3 * i + 2);
    }
    V loX = hn::Set(d, 1e300), loY = loX, hiX = hn::Set(d, -1e300), hiY = hiX;
    const V width = hn::Set(d, double(cam.width)), height = hn::Set(d, double(cam.height));
    const V half = hn::Set(d, 0.5);
    const auto extend = [&](auto mask, V x, V y, V w) {
        const V px = hn::Mul(hn::Mul(hn::Add(hn::Div(x, w), one), half), width);
        const V py = hn::Mul(hn::Mul(hn::Add(hn::Div(y, w), one), half), height);
        // glm::min(lo, p) is (p < lo ? p : lo), glm::max(hi, p) is (hi < p ? p : hi).
        loX = hn::IfThenElse(hn::And(mask, hn::Lt(px, loX)), px, loX);
        loY = hn::IfThenElse(hn::And(mask, hn::Lt(py, loY)), py, loY);
        hiX = hn::IfThenElse(hn::And(mask, hn::Lt(hiX, px)), px, hiX);
        hiY = hn::IfThenElse(hn::And(mask, hn::Lt(hiY, py)), py, hiY);
    };
    const int ring[4] = {0, 1, 3, 2}; // the strip's corners in polygon order
    for (int e = 0; e < 4; ++e) {
        const int a = ring[e], b = ring[(e + 1) % 4];
        const auto aIn = hn::Ge(qw[a], zNear), bIn = hn::Ge(qw[b], zNear);
        extend(aIn, qx[a], qy[a], qw[a]);
        // a + (b - a) ((a.w - zNear) / (a.w - b.w)), where the edge crosses zNear.
        const V t = hn::Div(hn::Sub(qw[a], zNear), hn::Sub(qw[a], qw[b]));
        const auto lerp = [&](V from, V to) {
            return hn::Add(from, hn::Mul(hn::Sub(to, from), t));
        };
        extend(hn::Xor(aIn, bIn), lerp(qx[a], qx[b]), lerp(qy[a], qy[b]), lerp(qw[a], qw[b]));
    }
    store(loX, kLo), store(loY, kLo + 1), store(hiX, kHi), store(hiY, kHi + 1);
}

/// The scalar tail of setupSpriteInto for one lane: culling in its order, then every field.
void WriteLane(const double* out, const float* outFloat, std::size_t N, std::size_t lane,
               const CameraFrame& cam, const RenderParams& params, const SpriteSetupJob& job) {
    const auto at = [&](int field) { return out[std::size_t(field) * N + lane]; };
    const auto at3 = [&](int field) { return glm::dvec3(at(field), at(field + 1), at(field + 2)); };
    const auto atFloat = [&](int field) { return outFloat[std::size_t(field) * N + lane]; };
    const auto gpu3 = [&](int field) {
        return glm::vec3(atFloat(field), atFloat(field + 1), atFloat(field + 2));
    };
    const SpriteConstants& k = *job.constants;
    SpriteSetup& S = *job.sprite;
    // The job's outputs beside the sprite, once its culling is known: its visibility, its depth
    // and its selectionInputs (with the parts the lanes derived).
    const auto writeJobOutputs = [&] {
        if (job.visible) *job.visible = S.visible();
        if (job.depth) *job.depth = S.gpu.depth;
        // Initialised in place from the prvalue (the callee writes the store's entry): assigned,
        // the inputs went through a stack temporary whose wide reloads waited on the callee's
        // narrower stores (a store-forwarding stall, a third of this function's samples).
        if (job.selection)
            new (job.selection) SpriteSelectionInputs(selectionInputs(
                S, DisplacementPredictor::fromParts(at3(kLineOfSight), at(kSigmaDepth)),
                at(kCellSizePx)));
    };
    S.cull = CullReason::None;
    S.entityId = job.entityId;
    S.model = k.model;
    S.frame = k.frame;
    S.pose = k.pose;
    S.centreRel = at3(kCentreRel);
    S.viewDepth = at(kViewDepth);
    S.distance = at(kDistance);
    S.radiusPx = at(kRadiusPx);
    const glm::ivec3 dims = k.dims;
    const CullReason early =
        cullBeforeLattice(at3(kEyeVoxel), dims, params.sigma, S.viewDepth, S.radiusPx, cam.zNear);
    if (early != CullReason::None) {
        markCulled(S, early);
        return writeJobOutputs();
    }

    SpriteLattice& L = S.lattice;
    L.dir = at3(kDir);
    L.right = at3(kRight);
    L.up = at3(kUp);
    L.centre = glm::dvec3(dims) * 0.5;
    L.gU = at(kGU);
    L.gV = at(kGV);
    L.sigma = params.sigma;
    L.maxDim = double(std::max({dims.x, dims.y, dims.z}));
    L.dims = dims;
    // Kept in a register for the GPU record's copy too: read back from the sprite, the four
    // int stores just made could not be forwarded to one 16-byte load, which stalled until they
    // reached the cache (a third of this function's time at 100,000 sprites).
    const glm::ivec4 cellRange{int(at(kCellRange)) - 2, int(at(kCellRange + 1)) + 2,
                               int(at(kCellRange + 2)) - 2, int(at(kCellRange + 3)) + 2};
    L.cellRange = cellRange;

    kernel::SpriteGpu& g = S.gpu;
    g = kernel::SpriteGpu{};
    g.mapI = gpu3(kFMapI);
    g.mapJ = gpu3(kFMapJ);
    g.mapDen = gpu3(kFMapDen);
    g.denMax = atFloat(kFDenMax);
    g.depth = atFloat(kFDepth);
    g.rayBase = gpu3(kFRayBase);
    g.cellRight = gpu3(kFCellRight);
    g.cellUp = gpu3(kFCellUp);
    g.dir = gpu3(kFDir);
    g.invDir = gpu3(kFInvDir);
    g.cellRange = cellRange;
    g.dims = glm::uvec4(glm::uvec3(dims), job.entityId);
    g.atlas = glm::uvec4(0u);
    g.skipEmpty = k.skipEmpty;
    g.faceLight0 = {k.light[0], k.light[1], k.light[2], k.light[3]};
    g.faceLight1 = {k.light[4], k.light[5], 0u, 0u};
    const float zNear = toGpuFloat(cam.zNear);
    for (int i = 0; i < 4; ++i)
        S.quad[std::size_t(i)] = glm::vec4(atFloat(kFQuad + 3 * i), atFloat(kFQuad + 3 * i + 1),
                                           zNear, atFloat(kFQuad + 3 * i + 2));
    setScreenRect(S, {at(kLo), at(kLo + 1)}, {at(kHi), at(kHi + 1)}, cam);
    writeJobOutputs();
}

void SetupSprites(std::span<const SpriteSetupJob> jobs, const CameraFrame& cam,
                  const RenderParams& params) {
    const D d;
    const std::size_t N = hn::Lanes(d);
    // Per field, N lanes (Highway's largest vector: 2048 bits of doubles).
    HWY_ALIGN double in[kInCount * HWY_MAX_BYTES / sizeof(double)];
    HWY_ALIGN double out[kOutCount * HWY_MAX_BYTES / sizeof(double)];
    HWY_ALIGN float outFloat[kFloatCount * HWY_MAX_BYTES / sizeof(double)];
    for (std::size_t first = 0; first < jobs.size(); first += N) {
        const std::size_t count = std::min(N, jobs.size() - first);
        for (std::size_t lane = 0; lane < N; ++lane) {
            // Lanes past the last job repeat the first: real inputs, results unused.
            const SpriteConstants& k = *jobs[first + (lane < count ? lane : 0)].constants;
            const auto put = [&](int field, double v) { in[std::size_t(field) * N + lane] = v; };
            for (int c = 0; c < 3; ++c)
                for (int r = 0; r < 3; ++r)
                    put(kRotation + 3 * c + r, k.pose.worldFromVoxelRotation[c][r]);
            for (int i = 0; i < 3; ++i) {
                put(kPosition + i, k.pose.position[i]);
                put(kAnchor + i, k.pose.anchor[i]);
                put(kDims + i, double(k.dims[i]));
            }
            put(kMetresPerVoxel, k.pose.metresPerVoxel);
            put(kMaxDim, double(std::max({k.dims.x, k.dims.y, k.dims.z})));
        }
        SetupLanes(cam, params, in, out, outFloat);
        for (std::size_t lane = 0; lane < count; ++lane)
            WriteLane(out, outFloat, N, lane, cam, params, jobs[first + lane]);
    }
}

const char* TargetName() {
    return hwy::TargetName(HWY_TARGET);
}
#else
void SetupSprites(std::span<const SpriteSetupJob> jobs, const CameraFrame& cam,
                  const RenderParams& params) {
    for (const SpriteSetupJob& job : jobs) {
        setupSpriteInto(*job.sprite, cam, *job.constants, job.entityId, params);
        if (job.selection) *job.selection = selectionInputs(*job.sprite);
        if (job.visible) *job.visible = job.sprite->visible();
        if (job.depth) *job.depth = job.sprite->gpu.depth;
    }
}
const char* TargetName() {
    return "scalar";
}
#endif

} // namespace HWY_NAMESPACE
} // namespace voxtier::sprite_setup_simd
HWY_AFTER_NAMESPACE();

#if HWY_ONCE
namespace voxtier {
namespace sprite_setup_simd {
HWY_EXPORT(SetupSprites);
HWY_EXPORT(TargetName);
} // namespace sprite_setup_simd

void setupSpritesInto(std::span<const SpriteSetupJob> jobs, const CameraFrame& camera,
                      const RenderParams& params) {
    HWY_DYNAMIC_DISPATCH(sprite_setup_simd::SetupSprites)(jobs, camera, params);
}

const char* spriteSetupSimdTarget() {
    return HWY_DYNAMIC_DISPATCH(sprite_setup_simd::TargetName)();
}
} // namespace voxtier
#endif
