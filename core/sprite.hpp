#pragma once
// The sprite contract of CONTRACT.md §3, per entity and frame, in double precision and
// camera-relative coordinates (the eye is subtracted before anything else, so an entity 10^6 m
// from the origin renders exactly like one at the origin). Both tiers and the tests call these
// functions; the per-pixel half lives in core/sprite_kernel.h.
#include "core/camera.hpp"
#include "core/scene.hpp"
#include "core/sprite_kernel.h"
#include "core/view_set.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <span>
#include <vector>

namespace voxtier {

/// Direction components smaller than this are set to exactly 0 (and the vector renormalised),
/// so canonical views have exactly zero components in both tiers (CONTRACT.md §7). Over a
/// 256-voxel traversal this moves a ray by < 3e-4 voxel.
inline constexpr double kDirectionSnap = 1e-6;
glm::dvec3 snapDirection(glm::dvec3 d);

/// §3.3 + §3.5: the virtual-pixel lattice of a model seen along `dir` (voxel space). Shared
/// by the near tier (dir = per-entity view direction, up from the camera) and the far tier's
/// snapshots (dir = -w, up from the model's +Z), so both rasterise the same lattice.
struct SpriteLattice {
    glm::dvec3 dir{0.0};       ///< ray direction d, unit, snapped
    glm::dvec3 right{0.0};     ///< cross(dir, up)
    glm::dvec3 up{0.0};        ///< unit, perpendicular to dir
    glm::dvec3 centre{0.0};    ///< model centre c = dims / 2
    double gU = 0.0, gV = 0.0; ///< floor(c) projected on the sprite plane, relative to c
    double sigma = 1.0;
    double maxDim = 1.0;
    glm::ivec3 dims{1};
    /// iMin, iMax, jMin, jMax: a superset of the cells that can be non-empty (incl. outline).
    glm::ivec4 cellRange{0};

    /// Centre of cell (i, j) on the sprite plane (voxel space).
    glm::dvec3 cellCentre(int i, int j) const {
        return centre + (gU + (i + 0.5) / sigma) * right + (gV + (j + 0.5) / sigma) * up;
    }
    /// §3.6: the cell's primary ray starts 2*maxDim in front of the plane.
    glm::dvec3 rayOrigin(int i, int j) const { return cellCentre(i, j) - dir * (2.0 * maxDim); }
    /// Cell containing the sprite-plane point `p` (voxel space, relative to the centre). Inline:
    /// the far blit calls it per footprint pixel.
    glm::ivec2 cellAt(glm::dvec3 p) const {
        return {int(std::floor(sigma * (glm::dot(p, right) - gU))),
                int(std::floor(sigma * (glm::dot(p, up) - gV)))};
    }
    int width() const { return cellRange.y - cellRange.x + 1; }
    int height() const { return cellRange.w - cellRange.z + 1; }
};

/// `upHint` must not be parallel to `dir`; `fallbackUp` is used when it nearly is.
SpriteLattice makeSpriteLattice(glm::dvec3 dir, glm::dvec3 upHint, glm::dvec3 fallbackUp,
                                glm::ivec3 dims, double sigma);

/// World <-> voxel for one entity (CONTRACT.md §2):
/// worldFromVoxel(p) = position + rotation * swizzle * metresPerVoxel * (p - anchor).
struct EntityPose {
    glm::dmat3 worldFromVoxelRotation{1.0}; ///< orthonormal: entity rotation * swizzle
    glm::dvec3 position{0.0};
    glm::dvec3 anchor{0.0};
    double metresPerVoxel = 1.0; ///< voxel size * entity scale

    /// Camera-relative world position of voxel-space point p (eye subtracted first).
    glm::dvec3 relativeWorld(glm::dvec3 p, glm::dvec3 eye) const {
        return (position - eye) + worldFromVoxelRotation * ((p - anchor) * metresPerVoxel);
    }
    glm::dvec3 voxelDirection(glm::dvec3 worldDir) const {
        return glm::transpose(worldFromVoxelRotation) * worldDir;
    }
    glm::dvec3 worldDirection(glm::dvec3 voxelDir) const {
        return worldFromVoxelRotation * voxelDir;
    }
    /// Voxel-space position of a world point, computed relative to the entity position.
    glm::dvec3 voxelPoint(glm::dvec3 world) const {
        return anchor +
               glm::transpose(worldFromVoxelRotation) * (world - position) / metresPerVoxel;
    }
};
/// Voxel -> world direction swizzle (CONTRACT.md §2): world = (v.x, v.z, -v.y).
glm::dmat3 worldFromVoxelSwizzle();
EntityPose makeEntityPose(const Entity& e, glm::ivec3 dims, double voxelSize);

/// Why an entity draws nothing this frame (in every tier: culling is part of the contract).
enum class CullReason {
    None,
    BehindCamera, ///< model centre not in front of the near plane
    CameraInside, ///< the eye is inside or on the proxy box (§3.9)
    SubPixel,     ///< projected bounding-sphere radius below half a pixel
    OffScreen,    ///< the proxy quad misses the viewport
};
const char* toString(CullReason r);

/// Everything one tier needs to draw one entity this frame.
struct SpriteSetup {
    CullReason cull = CullReason::None;
    std::uint32_t entityId = 0;
    int model = 0;
    int frame = 0;
    EntityPose pose;
    SpriteLattice lattice;
    glm::dvec3 centreRel{0.0}; ///< model centre minus eye (world)
    double viewDepth = 0.0;    ///< along the camera forward
    double distance = 0.0;     ///< |centreRel|
    double radiusPx = 0.0;     ///< projected bounding-sphere radius in pixels
    glm::ivec4 screenRect{0};  ///< x0, y0, x1, y1 (half-open), clamped to the image
    kernel::SpriteGpu gpu{};   ///< atlas / palette fields are filled in by the near tier
    /// Clip-space corners of the proxy quad on the sprite plane (triangle strip). Not in `gpu`:
    /// only the quad proxy draws it (from the hull buffer) and the hull's fallback reads it, while
    /// the near tier writes every visible sprite's record to the device each frame it moves.
    std::array<glm::vec4, 4> quad{};
    bool visible() const { return cull == CullReason::None; }
};

/// On-screen size (pixels) of one virtual pixel of a visible sprite: its projected
/// bounding-sphere radius over that radius in lattice cells. In core because both the error
/// budget (lod/) and the frame error report (compose/) measure displacement in it.
double cellSizePx(const SpriteSetup& sprite);

/// What the LOD selection reads of a sprite (lod/: the selector's inputs, the nearest view, the
/// predicted far displacement, the cost bound's sizes), in 96 bytes: the SpriteStore keeps it per
/// entity beside the sprites, written where a sprite is set up, so that a plan over 100,000 moving
/// entities reads these in entity order in place of three or four lines of each 640-byte sprite (on
/// two cores the planner's reads of the sprites were most of its 5.5 ms). Every field equals what
/// the planner computed from the sprite before, bit for bit (selectionInputs).
struct SpriteSelectionInputs {
    double distance = 0.0;        ///< SpriteSetup::distance
    double radiusPx = 0.0;        ///< SpriteSetup::radiusPx
    glm::dvec3 towardViewer{0.0}; ///< -lattice.dir (0 for a culled sprite)
    /// The sprite's far displacement against any view (predictedDisplacementVpx of its half
    /// extents, sigma and towardViewer); a culled sprite's predicts nothing and is never asked.
    DisplacementPredictor displacement;
    double cellSizePx = 0.0; ///< cellSizePx(sprite)
    /// cellCount and rectPixels of the sprite (core/near_rate.hpp; 0 for a culled one), saturated
    /// at 2^32 - 1: what the far tier's cost bound prices it by (BakeCosts), read here in place of
    /// two lines of the sprite (at 100,000 far tanks on two cores, ~3 ms of a frame's weighing).
    /// 32 bits, not 64: 8 bytes fewer to write per entity each update (~0.1 ms at 100,000); a
    /// rectangle is clamped to the image, and cells past 2^32 outnumber its pixels, so only a
    /// forced cell rate prices a sprite that large differently (as 2^32 - 1 cells).
    std::uint32_t cells = 0, rectPixels = 0;
    bool visible = false; ///< SpriteSetup::visible()
};
/// The selection inputs of one sprite (a culled one: its distance and radius, the rest 0).
SpriteSelectionInputs selectionInputs(const SpriteSetup& sprite);
/// The same with its two derived parts given (a visible sprite's displacement predictor and
/// cellSizePx, unread for a culled one): what the SIMD set-up calls with the parts its lanes
/// computed.
SpriteSelectionInputs selectionInputs(const SpriteSetup& sprite,
                                      const DisplacementPredictor& displacement, double cellSizePx);

/// §3.7 face light factors (16.16) for the six entered-face codes, given the light in world
/// space and the entity's rotation. Shared by the near kernel and the far blit.
std::array<std::uint32_t, 6> faceLightFactors(const Light& light, const EntityPose& pose);
/// Outward normal (voxel space) of the face a ray entered through, by face code 0..5.
glm::dvec3 faceNormal(unsigned faceCode);

/// What set-up derives from an entity alone, whatever the camera: its model frame and size,
/// its pose, the light factors of its faces and whether its rays skip empty space
/// (SpriteGpu::skipEmpty, from the frame's occupancy). A SpriteStore keeps it while the entity,
/// its animation frame, the light and that skip rule's answer stay as they were.
struct SpriteConstants {
    int model = 0;
    int frame = 0;
    glm::ivec3 dims{1};
    EntityPose pose;
    std::array<std::uint32_t, 6> light{};
    std::uint32_t skipEmpty = 0;
};
SpriteConstants spriteConstants(const Entity& entity, const VoxelModel& model, int frame,
                                const RenderParams& params, const Light& light);

/// The whole per-entity computation of §3.1-§3.10.
SpriteSetup setupSprite(const CameraFrame& camera, const Entity& entity, std::uint32_t entityId,
                        const VoxelModel& model, int frame, const RenderParams& params,
                        const Light& light);
/// setupSprite from the entity's constants, written over `sprite` in place (every field: the
/// result equals a fresh setupSprite's bit for bit).
void setupSpriteInto(SpriteSetup& sprite, const CameraFrame& camera,
                     const SpriteConstants& constants, std::uint32_t entityId,
                     const RenderParams& params);

/// Steps of setupSpriteInto that its SIMD form (setupSpritesInto) runs per sprite after its
/// vectors, written once for both (cullBeforeLattice and setScreenRect inline: out of line they
/// were a ninth of a moving 100,000-tank update's samples on two cores; the store alone 9.2-9.8
/// -> 8.8-9.5 ms inline):
/// §3.9's tests before the lattice, in their order: the eye inside the proxy box (`eyeVoxel`, the
/// eye in voxel space, against the box grown by one virtual pixel), the centre not beyond the near
/// plane, a projected radius below half a pixel. CullReason::None when the sprite goes on.
inline CullReason cullBeforeLattice(glm::dvec3 eyeVoxel, glm::ivec3 dims, double sigma,
                                    double viewDepth, double radiusPx, double zNear) {
    // The proxy box is the model bounds grown by one virtual pixel (§3.10).
    const double margin = 1.0 / sigma;
    if (eyeVoxel.x >= -margin && eyeVoxel.y >= -margin && eyeVoxel.z >= -margin &&
        eyeVoxel.x <= dims.x + margin && eyeVoxel.y <= dims.y + margin &&
        eyeVoxel.z <= dims.z + margin)
        return CullReason::CameraInside;
    if (!(viewDepth > zNear)) return CullReason::BehindCamera;
    if (radiusPx < 0.5) return CullReason::SubPixel;
    return CullReason::None;
}

/// A culled sprite's lattice, rectangle and GPU record: the defaults a fresh SpriteSetup holds.
void markCulled(SpriteSetup& sprite, CullReason why);
/// A sprite that setupSpriteInto set up from `constants` as they were but for their frame and
/// skip rule (SpriteConstants::frame, skipEmpty), brought to them in place: the only fields that
/// depend on either are the sprite's frame and its GPU record's skipEmpty, which a sprite culled
/// before its lattice leaves at the default (markCulled). What an animation step to a frame of
/// the same size changes (SpriteStore: two fields, where a set-up writes 640 bytes).
void restepSprite(SpriteSetup& sprite, const SpriteConstants& constants);
/// §3.10: the screen rectangle from the pixel bounds [lo, hi] of the proxy quad's part beyond
/// zNear (hi.x < lo.x: no such part), one pixel of margin, clamped to the image; OffScreen where
/// it is empty.
inline void setScreenRect(SpriteSetup& S, glm::dvec2 lo, glm::dvec2 hi, const CameraFrame& cam) {
    if (hi.x >= lo.x) {
        // Clamp in double first: a huge quad must not overflow the int conversion.
        const double W = cam.width, H = cam.height;
        S.screenRect = {int(std::clamp(std::floor(lo.x) - 1.0, 0.0, W)),
                        int(std::clamp(std::floor(lo.y) - 1.0, 0.0, H)),
                        int(std::clamp(std::ceil(hi.x) + 1.0, 0.0, W)),
                        int(std::clamp(std::ceil(hi.y) + 1.0, 0.0, H))};
    } else {
        S.screenRect = {0, 0, 0, 0}; // the whole quad is nearer than zNear
    }
    if (S.screenRect.x >= S.screenRect.z || S.screenRect.y >= S.screenRect.w)
        S.cull = CullReason::OffScreen;
}

/// One sprite for setupSpritesInto: where it goes, its entity's constants and id.
struct SpriteSetupJob {
    SpriteSetup* sprite = nullptr;
    const SpriteConstants* constants = nullptr;
    std::uint32_t entityId = 0;
    /// Where to write selectionInputs of the sprite too (none: nullptr). The SIMD set-up derives
    /// them on its lanes with the rest (on two cores, 100,000 of them derived one by one from the
    /// sprites just set up cost 1.6 ms).
    SpriteSelectionInputs* selection = nullptr;
    /// Where to write the sprite's visible() and its GPU record's depth too (each: none where
    /// nullptr): a store's per-entity copies, which a draw order reads in place of the sprites.
    /// Read back from the sprites after a batch, those two lines of each were a seventh of a
    /// moving 100,000-tank update's samples in the store's own loop on two cores.
    std::uint8_t* visible = nullptr;
    float* depth = nullptr;
};
/// setupSpriteInto for each job, the same bits, several sprites per SIMD instruction (the widest
/// unit this CPU has; core/sprite_setup_simd.cpp). What the sprite store calls: with a moving
/// camera every sprite is set up again each frame.
void setupSpritesInto(std::span<const SpriteSetupJob> jobs, const CameraFrame& camera,
                      const RenderParams& params);
/// The SIMD target setupSpritesInto runs on this CPU (Highway's name, or "scalar").
const char* spriteSetupSimdTarget();

/// setupSprite for every entity of the scene at time t (TBB-parallel). Index = entity id.
std::vector<SpriteSetup> setupSprites(const Scene& scene, const CameraFrame& camera, double time);

/// The depth / id rule every tier and the compositor share (§6): nearer wins (reversed-Z:
/// larger depth), equal depths go to the lower entity id, so nothing depends on draw order.
inline bool winsDepthTest(float depth, std::uint32_t id, float oldDepth, std::uint32_t oldId) {
    return depth > oldDepth || (depth == oldDepth && id < oldId);
}

} // namespace voxtier
