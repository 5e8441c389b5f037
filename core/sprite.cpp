#include "core/sprite.hpp"

#include "core/near_rate.hpp"

#include <glm/gtc/quaternion.hpp>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>

namespace voxtier {

namespace {

glm::dvec3 snapComponents(glm::dvec3 v) {
    for (int k = 0; k < 3; ++k)
        if (std::abs(v[k]) < kDirectionSnap) v[k] = 0.0;
    return v;
}

/// Float rounding for GPU inputs: finite, and subnormals flushed to 0 (llvmpipe and many GPUs
/// flush them, the CPU does not; flushing here keeps both sides on identical inputs).
float toGpuFloat(double v) {
    const float f = static_cast<float>(v);
    return std::abs(f) < 1.17549435e-38f ? 0.0f : f;
}
glm::vec3 toGpu(glm::dvec3 v) {
    return {toGpuFloat(v.x), toGpuFloat(v.y), toGpuFloat(v.z)};
}

/// Coefficients (a, b, c) with dot(pixelRay(x, y), A) = a*x + b*y + c, where pixelRay is the
/// camera-relative direction through framebuffer point (x, y), with unit forward component.
glm::dvec3 screenLinear(const CameraFrame& cam, glm::dvec3 a) {
    const double s = cam.pixelScale();
    const double ra = s * glm::dot(cam.right, a);
    const double ua = s * glm::dot(cam.up, a);
    return {ra, -ua, glm::dot(cam.forward, a) - 0.5 * cam.width * ra + 0.5 * cam.height * ua};
}

} // namespace

glm::dvec3 snapDirection(glm::dvec3 d) {
    d = glm::normalize(d);
    return glm::normalize(snapComponents(d));
}

SpriteLattice makeSpriteLattice(glm::dvec3 dir, glm::dvec3 upHint, glm::dvec3 fallbackUp,
                                glm::ivec3 dims, double sigma) {
    SpriteLattice L;
    L.dir = snapDirection(dir);
    glm::dvec3 up = upHint - glm::dot(upHint, L.dir) * L.dir;
    if (glm::length(up) < 1e-6 * std::max(1.0, glm::length(upHint)))
        up = fallbackUp - glm::dot(fallbackUp, L.dir) * L.dir;
    L.up = glm::normalize(snapComponents(glm::normalize(up)));
    L.right = glm::normalize(snapComponents(glm::cross(L.dir, L.up)));
    L.dims = dims;
    L.centre = glm::dvec3(dims) * 0.5;
    L.sigma = sigma;
    L.maxDim = double(std::max({dims.x, dims.y, dims.z}));
    // §3.5: the lattice is anchored at the voxel-lattice point floor(c), projected.
    const glm::dvec3 g = glm::floor(L.centre) - L.centre;
    L.gU = glm::dot(g, L.right);
    L.gV = glm::dot(g, L.up);
    // Footprint of the box [0, N]^3 on the plane, in cells, plus the outline ring and one
    // cell of slack for rounding: every cell outside this range is empty by construction.
    const glm::dvec3 half = L.centre;
    const double eu =
        half.x * std::abs(L.right.x) + half.y * std::abs(L.right.y) + half.z * std::abs(L.right.z);
    const double ev =
        half.x * std::abs(L.up.x) + half.y * std::abs(L.up.y) + half.z * std::abs(L.up.z);
    L.cellRange = {
        int(std::floor(sigma * (-eu - L.gU))) - 2, int(std::floor(sigma * (eu - L.gU))) + 2,
        int(std::floor(sigma * (-ev - L.gV))) - 2, int(std::floor(sigma * (ev - L.gV))) + 2};
    return L;
}

glm::dmat3 worldFromVoxelSwizzle() {
    // Columns are the world images of the voxel axes: x -> x, y -> -z, z -> y.
    return glm::dmat3(glm::dvec3(1, 0, 0), glm::dvec3(0, 0, -1), glm::dvec3(0, 1, 0));
}

EntityPose makeEntityPose(const Entity& e, glm::ivec3 dims, double voxelSize) {
    EntityPose p;
    p.worldFromVoxelRotation = glm::mat3_cast(glm::normalize(e.rotation)) * worldFromVoxelSwizzle();
    p.position = e.position;
    p.anchor = e.anchor.value_or(defaultAnchor(dims));
    p.metresPerVoxel = voxelSize * e.scale;
    return p;
}

const char* toString(CullReason r) {
    switch (r) {
    case CullReason::None:
        return "visible";
    case CullReason::BehindCamera:
        return "behind-camera";
    case CullReason::CameraInside:
        return "camera-inside";
    case CullReason::SubPixel:
        return "sub-pixel";
    case CullReason::OffScreen:
        return "off-screen";
    }
    return "?";
}

glm::dvec3 faceNormal(unsigned faceCode) {
    glm::dvec3 n(0.0);
    n[int(faceCode / 2)] = (faceCode % 2 == 0) ? -1.0 : 1.0;
    return n;
}

std::array<std::uint32_t, 6> faceLightFactors(const Light& light, const EntityPose& pose) {
    const double len = glm::length(light.direction);
    const glm::dvec3 l = len > 0.0 ? pose.voxelDirection(light.direction / len) : glm::dvec3(0.0);
    std::array<std::uint32_t, 6> f{};
    for (unsigned code = 0; code < 6; ++code) {
        const double k =
            light.ambient + light.diffuse * std::max(0.0, glm::dot(faceNormal(code), l));
        // Clamp to 4.0 so channel * factor stays far inside 32 bits in the kernel.
        f[code] = std::uint32_t(std::lround(std::clamp(k, 0.0, 4.0) * kernel::VT_LIGHT_ONE));
    }
    return f;
}

SpriteSetup setupSprite(const CameraFrame& cam, const Entity& entity, std::uint32_t entityId,
                        const VoxelModel& model, int frame, const RenderParams& params,
                        const Light& light) {
    SpriteSetup S;
    const SpriteConstants k = spriteConstants(entity, model, frame, params, light);
    setupSpriteInto(S, cam, k, entityId, params);
    return S;
}

SpriteConstants spriteConstants(const Entity& entity, const VoxelModel& model, int frame,
                                const RenderParams& params, const Light& light) {
    SpriteConstants k;
    k.model = entity.model;
    k.frame = frame;
    k.dims = model.frame(frame).dims();
    k.pose = makeEntityPose(entity, k.dims, params.voxelSize);
    k.light = faceLightFactors(light, k.pose);
    k.skipEmpty = model.bricks(frame).worthSkipping() ? 1u : 0u;
    return k;
}

void setupSpriteInto(SpriteSetup& S, const CameraFrame& cam, const SpriteConstants& constants,
                     std::uint32_t entityId, const RenderParams& params) {
    S.cull = CullReason::None;
    S.entityId = entityId;
    S.model = constants.model;
    S.frame = constants.frame;
    const glm::ivec3 dims = constants.dims;
    S.pose = constants.pose;
    const EntityPose& pose = S.pose;
    const double k = pose.metresPerVoxel;
    const double sigma = params.sigma;
    const glm::dvec3 c = glm::dvec3(dims) * 0.5;

    // §3.1 camera-relative centre, its depth and distance.
    S.centreRel = pose.relativeWorld(c, cam.eye);
    S.viewDepth = glm::dot(S.centreRel, cam.forward);
    S.distance = glm::length(S.centreRel);
    S.radiusPx = S.viewDepth > 0.0 ? glm::length(c) * k / S.viewDepth * cam.focalPx() : 0.0;

    // §3.9 culling (cullBeforeLattice). A culled sprite keeps the defaults of the fields below
    // (what a fresh SpriteSetup holds: markCulled).
    const glm::dvec3 eyeVoxel = pose.anchor + pose.voxelDirection(-(pose.position - cam.eye)) / k;
    const CullReason early =
        cullBeforeLattice(eyeVoxel, dims, sigma, S.viewDepth, S.radiusPx, cam.zNear);
    if (early != CullReason::None) return markCulled(S, early);

    // §3.2-§3.3: view direction and sprite basis, in voxel space.
    const glm::dvec3 dirWorld =
        params.viewMode == ViewMode::PerEntity ? S.centreRel / S.distance : cam.forward;
    S.lattice = makeSpriteLattice(pose.voxelDirection(dirWorld), pose.voxelDirection(cam.up),
                                  pose.voxelDirection(cam.forward), dims, sigma);
    const SpriteLattice& L = S.lattice;
    // The plane's basis back in world space (the snapped basis, so plane and lattice agree).
    const glm::dvec3 dW = pose.worldDirection(L.dir);
    const glm::dvec3 rW = pose.worldDirection(L.right);
    const glm::dvec3 uW = pose.worldDirection(L.up);

    // §3.4 exact screen -> sprite mapping. For the pixel ray r (unit forward component),
    // the plane point is p = (C.d / r.d) r - C, so
    //   u = ((C.d)(r.right) - (C.right)(r.d)) / (r.d)   [metres]
    // and sigma*(u/k - gU) is a ratio of affine functions of the pixel centre.
    const glm::dvec3 C = S.centreRel;
    const double Cd = glm::dot(C, dW), Cr = glm::dot(C, rW), Cu = glm::dot(C, uW);
    const glm::dvec3 den = screenLinear(cam, dW);
    const glm::dvec3 numI =
        (sigma / k) * (Cd * screenLinear(cam, rW) - Cr * den) - sigma * L.gU * den;
    const glm::dvec3 numJ =
        (sigma / k) * (Cd * screenLinear(cam, uW) - Cu * den) - sigma * L.gV * den;

    kernel::SpriteGpu& g = S.gpu;
    g = kernel::SpriteGpu{};
    g.mapI = toGpu(numI);
    g.mapJ = toGpu(numJ);
    g.mapDen = toGpu(den);
    g.denMax = toGpuFloat(Cd / (2.0 * cam.zNear));
    g.depth = toGpuFloat(cam.zNear / S.viewDepth); // §3.8, reversed-Z
    g.rayBase = toGpu(L.centre + L.gU * L.right + L.gV * L.up - L.dir * (2.0 * L.maxDim));
    g.cellRight = toGpu(L.right / sigma);
    g.cellUp = toGpu(L.up / sigma);
    g.dir = toGpu(L.dir);
    g.invDir =
        toGpu(glm::dvec3(L.dir.x != 0.0 ? 1.0 / L.dir.x : 0.0, L.dir.y != 0.0 ? 1.0 / L.dir.y : 0.0,
                         L.dir.z != 0.0 ? 1.0 / L.dir.z : 0.0));
    g.cellRange = L.cellRange;
    g.dims = glm::uvec4(glm::uvec3(dims), entityId);
    g.atlas = glm::uvec4(0u);
    g.skipEmpty = constants.skipEmpty;
    const auto& light6 = constants.light;
    g.faceLight0 = {light6[0], light6[1], light6[2], light6[3]};
    g.faceLight1 = {light6[4], light6[5], 0u, 0u};

    // §3.10 proxy: a quad on the sprite plane covering the cell range plus one cell and two
    // pixels of margin, so rasterisation rules never decide a drawn pixel (the kernel does).
    const double marginVox = 1.0 / sigma + 2.0 * cam.pixelScale() * S.viewDepth / k;
    const double u0 = L.gU + (L.cellRange.x - 1) / sigma - marginVox;
    const double u1 = L.gU + (L.cellRange.y + 2) / sigma + marginVox;
    const double v0 = L.gV + (L.cellRange.z - 1) / sigma - marginVox;
    const double v1 = L.gV + (L.cellRange.w + 2) / sigma + marginVox;
    const glm::dvec2 corners[4] = {{u0, v0}, {u1, v0}, {u0, v1}, {u1, v1}}; // triangle strip
    glm::dvec4 clip[4];
    for (int i = 0; i < 4; ++i) {
        const glm::dvec3 P = C + k * (corners[i].x * rW + corners[i].y * uW);
        clip[i] = clipFromCameraRelative(cam, P);
        S.quad[std::size_t(i)] = glm::vec4(toGpuFloat(clip[i].x), toGpuFloat(clip[i].y),
                                           toGpuFloat(clip[i].z), toGpuFloat(clip[i].w));
    }
    // The screen rectangle: the bounds of the quad's part at view depth >= zNear (the kernel
    // draws only where the pixel ray meets the plane at >= 2 zNear, vtPixelCell's denMax), the
    // quad clipped there in clip space, where depth is linear. Unclipped, a quad crossing the
    // near plane would claim the whole image, and every cell-rate pass and reference row walks
    // the rectangle.
    glm::dvec2 lo(1e300), hi(-1e300);
    const auto extend = [&](const glm::dvec4& c) {
        const glm::dvec2 px{(c.x / c.w + 1.0) * 0.5 * cam.width,
                            (c.y / c.w + 1.0) * 0.5 * cam.height};
        lo = glm::min(lo, px);
        hi = glm::max(hi, px);
    };
    const int ring[4] = {0, 1, 3, 2}; // the strip's corners in polygon order
    for (int e = 0; e < 4; ++e) {
        const glm::dvec4& a = clip[ring[e]];
        const glm::dvec4& b = clip[ring[(e + 1) % 4]];
        const bool aIn = a.w >= cam.zNear, bIn = b.w >= cam.zNear;
        if (aIn) extend(a);
        if (aIn != bIn) extend(a + (b - a) * ((a.w - cam.zNear) / (a.w - b.w)));
    }
    setScreenRect(S, lo, hi, cam);
}

void markCulled(SpriteSetup& S, CullReason why) {
    S.cull = why;
    S.lattice = SpriteLattice{};
    S.screenRect = glm::ivec4(0);
    S.gpu = kernel::SpriteGpu{};
    S.quad = {};
}

void restepSprite(SpriteSetup& S, const SpriteConstants& constants) {
    S.frame = constants.frame;
    // The record is filled past the culling before the lattice: visible, or culled only by the
    // rectangle (setScreenRect comes last).
    if (S.cull == CullReason::None || S.cull == CullReason::OffScreen)
        S.gpu.skipEmpty = constants.skipEmpty;
}

double cellSizePx(const SpriteSetup& sprite) {
    const double radiusCells =
        glm::length(glm::dvec3(sprite.lattice.dims) * 0.5) * sprite.lattice.sigma;
    return radiusCells > 0.0 ? sprite.radiusPx / radiusCells : 0.0;
}

SpriteSelectionInputs selectionInputs(const SpriteSetup& sprite) {
    if (!sprite.visible()) return selectionInputs(sprite, {}, 0.0);
    return selectionInputs(sprite,
                           DisplacementPredictor(glm::dvec3(sprite.lattice.dims) * 0.5,
                                                 sprite.lattice.sigma, -sprite.lattice.dir),
                           cellSizePx(sprite));
}

SpriteSelectionInputs selectionInputs(const SpriteSetup& sprite,
                                      const DisplacementPredictor& displacement,
                                      double cellSizePx) {
    SpriteSelectionInputs in;
    in.distance = sprite.distance;
    in.radiusPx = sprite.radiusPx;
    in.visible = sprite.visible();
    if (!in.visible) return in;
    in.towardViewer = -sprite.lattice.dir;
    in.displacement = displacement;
    in.cellSizePx = cellSizePx;
    in.cells = std::uint32_t(std::min<std::uint64_t>(cellCount(sprite), 0xFFFFFFFFu));
    in.rectPixels = std::uint32_t(std::min<std::uint64_t>(rectPixels(sprite), 0xFFFFFFFFu));
    return in;
}

std::vector<SpriteSetup> setupSprites(const Scene& scene, const CameraFrame& camera, double time) {
    std::vector<SpriteSetup> out(scene.entities.size());
    tbb::parallel_for(std::size_t(0), out.size(), [&](std::size_t i) {
        const Entity& e = scene.entities[i];
        const VoxelModel& m = *scene.models.at(std::size_t(e.model));
        out[i] = setupSprite(camera, e, std::uint32_t(i), m, e.frameAt(m, time), scene.render,
                             scene.light);
    });
    return out;
}

} // namespace voxtier
