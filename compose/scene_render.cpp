#include "compose/scene_render.hpp"

#include <algorithm>
#include <cmath>
#include <utility>

namespace voxtier {

void applyCameraRule(Scene& scene, SceneCamera camera) {
    if (camera == SceneCamera::Still && scene.cameraPositioned) scene.path.reset();
}

int frameAtTime(const Scene& scene, double time) {
    if (!scene.path) return 0;
    // The epsilon keeps a frame's own time (start + k / fps) in frame k.
    return std::max(
        0, int(std::floor((time - scene.path->keys.front().time) * scene.path->fps + 1e-9)));
}

SceneRenderer::SceneRenderer(Scene scene, SceneCamera camera, FrameOptions options)
    : scene_((applyCameraRule(scene, camera), std::move(scene))), frames_(scene_, options) {}

FrameResult SceneRenderer::render(int frame, RenderMode mode) {
    frames_.applyEditsThrough(frame);
    return frames_.render(scene_.timeOfFrame(frame), mode, frame);
}

FrameResult SceneRenderer::renderAt(double time, RenderMode mode) {
    const int frame = frameAtTime(scene_, time);
    frames_.applyEditsThrough(frame);
    return frames_.render(time, mode, frame);
}

FrameResult renderStill(const Scene& scene, const FrameOptions& options) {
    SceneRenderer renderer(scene, SceneCamera::Still, options);
    return renderer.render(0, RenderMode::Hybrid);
}

} // namespace voxtier
