#pragma once
// A scene: render parameters, camera (and optional camera path), light, models, entities,
// selector thresholds and scripted edits. Loaded from JSON by core/scene_loader.hpp.
#include "core/camera.hpp"
#include "core/voxel_model.hpp"

#include <glm/gtc/quaternion.hpp>

#include <cmath>
#include <memory>
#include <optional>
#include <string>
#include <vector>

namespace voxtier {

/// Which way each sprite's parallel rays point (CONTRACT.md §3.2).
enum class ViewMode {
    PerEntity, ///< normalize(model centre - eye): each sprite faces the viewer (default)
    Parallel,  ///< the camera forward for every sprite
};

struct RenderParams {
    double voxelSize = 0.1; ///< metres per voxel (before entity scale)
    double sigma = 1.0;     ///< virtual pixels per voxel (σ)
    ViewMode viewMode = ViewMode::PerEntity;
    Rgba8 background = packRgba(40, 44, 52);
};

/// Directional light; `direction` points from the surface towards the light (world space).
struct Light {
    glm::dvec3 direction{-0.35, 0.8, 0.5};
    double ambient = 0.45;
    double diffuse = 0.55;
};

/// Entity tier selector settings (CONTRACT.md §5).
enum class SelectorMetric {
    Distance, ///< metres from the eye to the model centre: grows with distance
    RadiusPx, ///< projected bounding-sphere radius in pixels: shrinks with distance
    ErrorPx,  ///< predicted view-quantisation error r_px * sin(theta): shrinks with distance
    /// The far tier's predicted silhouette displacement (CONTRACT.md §5) from the best view of the
    /// refinement ladder, as a share of budgetVpx: shrinks with distance. The compositor picks
    /// the coarsest ladder view within the budget (lod/error_budget.hpp).
    ErrorBudget,
};
/// The scene file's name of a metric: "distance", "radius_px", "error_px" or "error_budget".
const char* toString(SelectorMetric m);

/// Hysteresis (lod/selector.hpp). Distance: near->far when the metric rises past farAt,
/// far->near when it falls below nearAt < farAt. The pixel metrics shrink with distance, so
/// their band is mirrored: near->far when the metric falls below farAt, far->near when it rises
/// past nearAt > farAt. Either way the band width is |farAt - nearAt|.
struct SelectorConfig {
    SelectorMetric metric = SelectorMetric::Distance;
    double nearAt = 30.0;           ///< back to near when the metric crosses this (towards "near")
    double farAt = 40.0;            ///< to far when the metric crosses this (towards "far")
    double viewHysteresisDeg = 0.0; ///< far tier: switch snapshot view only when closer by this
    int crossfadeFrames = 0;        ///< 0 = switch instantly
    int viewSetSize = 26;           ///< 26, 98 or 218 snapshot directions
    /// ErrorBudget: the displacement allowed, in virtual pixels where one covers at least a
    /// screen pixel, in screen pixels where it covers less; near_at / far_at are shares of it.
    double budgetVpx = 1.0;
    /// ErrorBudget: the finest ladder level n used (1, 2, 4, ... 64). 16 (6,146 views, gaps up
    /// to 2.5 degrees): a sprite that needs a finer view is large on screen, its view changes
    /// every few frames of a moving camera, and a bake costs more than drawing it near.
    int ladderCap = 16;
    /// ErrorBudget: snapshots a frame may bake; past it, an entity is drawn near this frame. Once
    /// bakes and near frames are measured the cost bound (CONTRACT.md §5) decides which bakes pay;
    /// this bound is what is left before that, and a cap on a burst. Why 512:
    /// docs/decisions/bake-cap-and-scene-budget.md.
    int maxBakesPerFrame = 512;
    /// Far tier: snapshots are baked at snapshotScale x the sprite's sigma (1-4), so a read lands
    /// within half a snapshot cell, 1/(2k) of a near cell, of where it aims; bake time and bytes
    /// grow by k^2. With an odd k a canonical view's near cell centres are snapshot cell centres,
    /// so far == near stays exact there.
    int snapshotScale = 1;
    bool operator==(const SelectorConfig&) const = default;
};
/// The finest snapshots a scene may ask for (SelectorConfig::snapshotScale, 1 to this): past 4,
/// k^2 the bake cost buys little (CONTRACT.md §4), and snapshot files bound their stride by it.
inline constexpr int kMaxSnapshotScale = 4;
/// Defaults per metric: 30/40 m; 24/16 px radius; 1.0/0.5 px predicted error; for the budget,
/// far below 0.75 of it and near again above all of it (a far entity never exceeds it).
inline SelectorConfig defaultSelectorFor(SelectorMetric m) {
    SelectorConfig c;
    c.metric = m;
    if (m == SelectorMetric::RadiusPx) c.nearAt = 24.0, c.farAt = 16.0;
    if (m == SelectorMetric::ErrorPx) c.nearAt = 1.0, c.farAt = 0.5;
    if (m == SelectorMetric::ErrorBudget) c.nearAt = 1.0, c.farAt = 0.75;
    return c;
}

struct Entity {
    int model = 0;            ///< index into Scene::models
    int frame = 0;            ///< animation frame at time 0
    double fps = 0.0;         ///< animation frames per second (0 = static)
    glm::dvec3 position{0.0}; ///< world position of the anchor
    glm::dquat rotation{1.0, 0.0, 0.0, 0.0};
    double scale = 1.0;               ///< uniform
    std::optional<glm::dvec3> anchor; ///< voxel-space anchor; default bottom centre (sx/2, sy/2, 0)
    std::string name;

    /// Animation frame at time t (seconds), wrapped to the model's frame count.
    int frameAt(const VoxelModel& m, double t) const {
        return m.wrapFrame(frame + (fps > 0.0 ? static_cast<long long>(std::floor(t * fps)) : 0));
    }
};

struct CameraKey {
    double time = 0.0;
    glm::dvec3 position{0.0};
    glm::dvec3 target{0.0};
    std::optional<glm::dvec3> up;
    std::optional<double> fovYDeg;
};

/// Keyframed camera path, linearly interpolated; `fps` turns frame numbers into times.
struct CameraPath {
    std::vector<CameraKey> keys; ///< sorted by time, at least one
    double fps = 30.0;
    double duration() const { return keys.empty() ? 0.0 : keys.back().time - keys.front().time; }
    int frameCount() const { return int(std::floor(duration() * fps + 1e-9)) + 1; }
};

struct ScriptedEdit {
    enum class Op { Set, Fill, Clear };
    int atFrame = 0;    ///< applied before rendering this path frame
    int model = 0;      ///< index into Scene::models
    int modelFrame = 0; ///< which animation frame of the model
    Op op = Op::Set;
    Box3i box; ///< Set: a single voxel box
    std::uint8_t index = 1;
};

/// A ground plane y = height with a grid, for context (drawn by compose/backdrop.hpp wherever no
/// sprite is, fading into the background with distance from the eye).
struct GroundPlane {
    double height = 0.0;        ///< world y, metres
    double spacing = 1.0;       ///< grid line spacing, metres
    double lineWidth = 0.03;    ///< metres
    double fadeDistance = 80.0; ///< metres from the eye at which only the background is left
    Rgba8 color = packRgba(62, 68, 78);
    Rgba8 lineColor = packRgba(98, 106, 120);
};

struct Scene {
    std::string source; ///< file it came from (for messages)
    RenderParams render;
    Camera camera;
    /// The file's "camera" gives a position: a plain render (no --path, --frame, --time) shows
    /// this camera even when there is a path; without one it shows the path at its first frame.
    bool cameraPositioned = false;
    std::optional<CameraPath> path;
    Light light;
    std::optional<GroundPlane> ground;
    SelectorConfig selector;
    std::vector<std::shared_ptr<VoxelModel>> models;
    std::vector<Entity> entities;
    std::vector<ScriptedEdit> edits;

    /// The camera at time t: the path's interpolation when there is a path, else `camera`
    /// (image size and near plane always come from `camera`).
    Camera cameraAt(double t) const;
    double timeOfFrame(int frame) const {
        return path ? path->keys.front().time + frame / path->fps : frame / 30.0;
    }
};

/// The default voxel-space anchor of a model frame: bottom centre (sx/2, sy/2, 0).
inline glm::dvec3 defaultAnchor(glm::ivec3 dims) {
    return {dims.x * 0.5, dims.y * 0.5, 0.0};
}

} // namespace voxtier
