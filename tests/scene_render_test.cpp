// compose/scene_render.hpp, the library's entry point: the camera rule and the frame steps of
// `voxtier render` (the CLI's images are compared byte for byte in tests/example_test.sh).
#include "compose/scene_render.hpp"
#include "core/scene_loader.hpp"
#include "test_support.hpp"

#include <gtest/gtest.h>

namespace voxtier {
namespace {

/// scenes/default.json, small: its file positions the camera (the path's last key) and has a path.
Scene smallDefaultScene() {
    Scene s = loadScene(test::sourcePath("scenes/default.json"));
    s.camera.width = 160;
    s.camera.height = 90;
    return s;
}

FrameOptions cpuOptions() {
    FrameOptions o;
    o.nearBackend = NearBackend::Reference;
    o.farBackend = FarBackend::Cpu;
    return o;
}

TEST(SceneRender, TheStillDropsThePathOnlyWhereTheFilePositionsTheCamera) {
    Scene positioned = smallDefaultScene();
    ASSERT_TRUE(positioned.cameraPositioned && positioned.path);
    Scene followed = positioned;
    applyCameraRule(positioned, SceneCamera::Still);
    applyCameraRule(followed, SceneCamera::Path);
    EXPECT_FALSE(positioned.path);
    EXPECT_TRUE(followed.path);
    Scene unpositioned = smallDefaultScene();
    unpositioned.cameraPositioned = false;
    applyCameraRule(unpositioned, SceneCamera::Still);
    EXPECT_TRUE(unpositioned.path); // the still is the path's first frame
}

TEST(SceneRender, FrameAtTimeIsThePathFrameTheTimeFallsIn) {
    Scene s = smallDefaultScene();
    ASSERT_EQ(s.path->fps, 30.0);
    EXPECT_EQ(frameAtTime(s, 0.0), 0);
    EXPECT_EQ(frameAtTime(s, 1.0), 30);        // a frame's own time is in that frame
    EXPECT_EQ(frameAtTime(s, 1.0 + 1e-3), 30); // and so is a time just past it
    EXPECT_EQ(frameAtTime(s, 1.0 / 30.0 * 7), 7);
    EXPECT_EQ(frameAtTime(s, -1.0), 0);
    s.path.reset();
    EXPECT_EQ(frameAtTime(s, 5.0), 0); // without a path, edits go by frame 0
}

// The still is the frame FrameRenderer draws of the scene with its path dropped (what
// apps/cmd_render.cpp used to do itself), not the path's first frame.
TEST(SceneRender, RenderStillDrawsTheStaticCamerasFrame) {
    const Scene scene = smallDefaultScene();
    const FrameResult still = renderStill(scene, cpuOptions());

    Scene withoutPath = scene;
    withoutPath.path.reset();
    FrameRenderer direct(withoutPath, cpuOptions());
    EXPECT_EQ(test::describeDifference(still.image, direct.render(0.0, RenderMode::Hybrid).image,
                                       "renderStill", "FrameRenderer"),
              "");

    SceneRenderer path(scene, SceneCamera::Path, cpuOptions());
    EXPECT_NE(still.image.color, path.render(0).image.color)
        << "the path's first frame is not the static camera's";
}

// --time T: the frame at T itself, not at its path frame's time.
TEST(SceneRender, RenderAtDrawsTheTimeGiven) {
    const Scene scene = smallDefaultScene();
    SceneRenderer at(scene, SceneCamera::Path, cpuOptions());
    const double t = 1.0 + 0.5 / 30.0; // half-way between frames 30 and 31
    const Image image = at.renderAt(t).image;
    Scene copy = scene;
    FrameRenderer direct(copy, cpuOptions());
    EXPECT_EQ(test::describeDifference(image, direct.render(t, RenderMode::Hybrid).image,
                                       "renderAt", "FrameRenderer"),
              "");
    SceneRenderer frame(scene, SceneCamera::Path, cpuOptions());
    EXPECT_NE(image.color, frame.render(30).image.color) << "the camera moves within a frame";
}

} // namespace
} // namespace voxtier
