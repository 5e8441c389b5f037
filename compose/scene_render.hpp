#pragma once
// The library's entry point for drawing a scene as `voxtier render` does (docs/library.md): the
// camera rule of docs/scenes.md ("Which camera a render uses") and the steps around each frame
// (the scripted edits due, then the frame at its path time). The CLI's render command draws
// through SceneRenderer, so a program that does the same with the same FrameOptions gets the
// CLI's image, byte for byte (examples/render_scene checks it).
#include "compose/frame.hpp"
#include "core/scene.hpp"

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

} // namespace voxtier
