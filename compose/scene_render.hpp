#pragma once
// The library's entry point for drawing a scene as `voxtier render` does (docs/library.md): the
// camera rule of docs/scenes.md ("Which camera a render uses") and the steps around each frame
// (the scripted edits due, then the frame at its path time). The CLI's render command draws
// through SceneRenderer, so a program that does the same with the same FrameOptions gets the
// CLI's image, byte for byte (examples/render_scene checks it).
#include "compose/frame.hpp"
#include "core/scene.hpp"
#include "core/view_set.hpp"

#include <functional>
#include <optional>
#include <vector>

namespace voxtier {

/// Which camera a render follows.
enum class SceneCamera {
    /// `voxtier render SCENE.json` with no frame option: the static camera where the scene file
    /// positions it (`camera.position`, Scene::cameraPositioned), even when the file also has a
    /// camera path; otherwise the path at its first frame.
    Still,
    /// `--path`, `--frames`, `--frame N`, `--time T`: the camera path (a scene without one keeps
    /// its static camera, and the frame or time only moves the animation clock).
    Path,
};

/// The camera rule: `scene` as a render that follows `camera` sees it (Still drops the camera
/// path of a scene whose file positions its camera; Path changes nothing).
void applyCameraRule(Scene& scene, SceneCamera camera);

/// The path frame that time `time` (seconds) falls in: the frame whose scripted edits a `--time`
/// render applies: 0 before the path's first key, and 0 for a scene without a path.
int frameAtTime(const Scene& scene, double time);

/// Frames of one scene, drawn as `voxtier render` draws them. Owns the scene (its models are
/// shared with the Scene passed in, and scripted edits change them) and the FrameRenderer that
/// keeps what persists between frames: the selector's state, the snapshot cache, the device.
class SceneRenderer {
  public:
    SceneRenderer(Scene scene, SceneCamera camera, FrameOptions options = {});
    SceneRenderer(const SceneRenderer&) = delete;
    SceneRenderer& operator=(const SceneRenderer&) = delete;

    /// Path frame `frame` at its time (Scene::timeOfFrame), after the scripted edits due by it.
    /// A still render is frame 0. Consecutive calls are consecutive frames for the selector
    /// (hysteresis, cross-fades), as `--path` and `--frames` draw them; the first call starts
    /// it fresh, as a lone `--frame N` does.
    FrameResult render(int frame = 0, RenderMode mode = RenderMode::Hybrid);
    /// `--time T`: the frame at time `time`, after the edits due by frameAtTime(scene(), time).
    FrameResult renderAt(double time, RenderMode mode = RenderMode::Hybrid);
    /// render() and renderAt() in two halves (FrameRenderer::submit, finished by
    /// frames().finish()): a sequence keeps two frames in flight. `selected` as submit's.
    FrameRenderer::PendingFrame submit(int frame = 0, RenderMode mode = RenderMode::Hybrid,
                                       const std::function<void()>& selected = {});
    FrameRenderer::PendingFrame submitAt(double time, RenderMode mode = RenderMode::Hybrid,
                                         const std::function<void()>& selected = {});

    /// The scene as drawn: the camera rule applied, the edits applied so far.
    const Scene& scene() const { return scene_; }
    FrameRenderer& frames() { return frames_; }

  private:
    Scene scene_;
    FrameRenderer frames_;
};

/// The image `voxtier render SCENE.json -o FILE` writes with no other option: the still camera
/// (SceneCamera::Still), one hybrid frame, `options` as the CLI's defaults are FrameOptions'.
FrameResult renderStill(const Scene& scene, const FrameOptions& options = {});

/// The snapshots of one model frame that renders of a scene ask for (snapshotsRendersAskFor).
struct SnapshotNeed {
    int model = 0; ///< index into Scene::models
    int frame = 0; ///< the model's animation frame
    /// The voxels the snapshots are of: the model frame as loaded (-1), or after the scripted
    /// edits due by this path frame (Scene::edits with atFrame <= editedAt).
    int editedAt = -1;
    double sigma = 1.0;        ///< the sprites' (baked at this x SelectorConfig::snapshotScale)
    std::vector<ViewId> views; ///< distinct, ascending by lattice vector
};

/// How far past the renders' own requests snapshotsRendersAskFor looks.
struct SnapshotNeedOptions {
    /// The renders' mode: Hybrid (the selector's views) or Far (every visible entity, from its
    /// view set's nearest view). Near and Reference frames ask for no snapshot.
    RenderMode mode = RenderMode::Hybrid;
    /// The margin, for every frame: nullopt asks only what the still and the path's frames in
    /// order ask for. 0 adds, for every entity, the view a fresh selector picks (a lone
    /// `--frame N` or `--time T` render, or a render that starts part-way along the path);
    /// D > 0 adds also what it picks with the entity seen from 8 directions D degrees off its
    /// own (a camera up to D degrees off the path, as seen from the entity).
    std::optional<double> marginDeg = 0.0;
};

struct SnapshotNeeds {
    /// In the order to bake them: editedAt ascending (apply each's edits, then bake it), then
    /// model, frame and sigma.
    std::vector<SnapshotNeed> needs;
    bool still = false; ///< a still render of its own (a positioned camera, or no path)
    /// Frames followed in order: the camera path's, or without one, the static camera over the
    /// longest animation loop at 30 frames a second (at most kMaxPathlessFrames); 0 if neither.
    int frames = 0;
    std::size_t snapshots() const;
};
/// The longest animation a scene without a camera path is followed over (frames at 30 a second).
inline constexpr int kMaxPathlessFrames = 3000;

/// The snapshots `voxtier render` asks the snapshot cache for when it draws `scene` as a still
/// and along its camera path, every frame in order (SceneRenderer), plus `options`' margin: what
/// `voxtier bake SCENE` pre-bakes. Planned by the renders' own planner (lod/frame_planner.hpp)
/// as it plans against a directory that holds every one of them, where nothing is baked, so no
/// bake bound or cost bound binds: a render whose on-disk cache holds these bakes none of them,
/// and draws the image it draws when it bakes them itself wherever its bounds do not bind.
/// Assumes the render's memory cache keeps what it read (true within its budget) and its
/// FrameOptions::cacheDir holds them all; after a scripted edit a render refreshes the views it
/// already holds of the edited model frame instead of reading them (SnapshotCache).
SnapshotNeeds snapshotsRendersAskFor(const Scene& scene, const SnapshotNeedOptions& options = {});

} // namespace voxtier
