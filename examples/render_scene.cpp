// Renders a scene through the voxtier library exactly as the CLI does:
//
//   render_scene SCENE.json OUT.png          = voxtier render SCENE.json -o OUT.png
//   render_scene SCENE.json OUT.png FRAME    = voxtier render SCENE.json -o OUT.png --frame FRAME
//
// and writes the same file, byte for byte (tests/example_test.sh checks both, in the build tree
// and against an installed one). The output format follows OUT's extension, as the CLI's does.
#include <voxtier/compose/scene_render.hpp>
#include <voxtier/core/error.hpp>
#include <voxtier/core/scene_loader.hpp>
#include <voxtier/image_files/image_files.hpp>

#include <cstdio>
#include <exception>
#include <string>
#include <utility>

int main(int argc, char** argv) {
    if (argc != 3 && argc != 4) {
        std::fprintf(stderr, "usage: render_scene SCENE.json OUT.png [FRAME]\n");
        return 2;
    }
    try {
        // A scene file names its models relative to itself; errors name the file and the field.
        voxtier::Scene scene = voxtier::loadScene(argv[1]);
        // Without a frame, the still camera (the scene file's camera where it positions one,
        // else its path's first frame); with one, that frame of the camera path.
        const bool still = argc == 3;
        const int frame = still ? 0 : std::stoi(argv[3]);
        if (frame < 0 || (scene.path && frame >= scene.path->frameCount()))
            throw voxtier::InputError(
                argv[1], "FRAME", "frame " + std::to_string(frame) + " is not on the camera path");
        // FrameOptions{} are the CLI's defaults: the near tier on Vulkan on a GPU, else the CPU
        // reference tracer (the same pixels), a 256 MiB snapshot cache, no on-disk cache.
        voxtier::SceneRenderer renderer(
            std::move(scene), still ? voxtier::SceneCamera::Still : voxtier::SceneCamera::Path,
            voxtier::FrameOptions{});
        const voxtier::FrameResult result = renderer.render(frame, voxtier::RenderMode::Hybrid);
        // zNear: an EXR's depth channel is written in view metres.
        voxtier::writeImage(argv[2], result.image, renderer.scene().camera.zNear);
        std::printf("%s: frame %d, %d entities, %d near and %d far sprites -> %s\n", argv[1], frame,
                    result.stats.entities, result.stats.nearDrawn, result.stats.farDrawn, argv[2]);
    } catch (const std::exception& e) {
        std::fprintf(stderr, "render_scene: error: %s\n", e.what());
        return 1;
    }
    return 0;
}
