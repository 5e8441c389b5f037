// `voxtier check SCENE...`: the identity the near tier promises (DESIGN.md §3), checked by the
// shipped binary itself on the machine it runs on: each scene drawn by the Vulkan near tier and by
// the CPU reference tracer, compared in memory plane by plane (colour, depth bits, entity id).
// It first prints the memory type each buffer class gets on this device (type, flags, heap), and
// any installed Vulkan driver whose library does not load (and why).
// The same comparison as tests/vulkan_identity_test.cpp, for a machine that has the CLI but not
// the test suite (the portable folder, tools/gpu_check.sh). Exit status 1 when any pixel differs.
#include "apps/commands.hpp"
#include "core/camera.hpp"
#include "core/error.hpp"
#include "core/file_write.hpp"
#include "core/scene_loader.hpp"
#include "core/sprite.hpp"
#include "core/sprite_kernel.h"
#include "device/icd_diagnosis.hpp"
#include "device/vulkan_device_info.hpp"
#include "device/vulkan_options.hpp"
#include "volumetric/near_renderer.hpp"
#include "volumetric/reference_renderer.hpp"

#include <algorithm>
#include <cstdio>
#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

namespace voxtier::cli {

namespace {

struct CheckArgs {
    std::vector<std::string> scenes;
    std::string csv;
    bool validation = false;
};

std::size_t drawnPixels(const Image& img) {
    return std::size_t(std::count_if(img.id.begin(), img.id.end(),
                                     [](std::uint32_t v) { return v != kernel::VT_NO_ENTITY; }));
}

void run(const CheckArgs& a) {
    const VulkanDeviceInfo device = describeVulkanDevice();
    if (!device.found) throw std::runtime_error(device.whyNone);
    std::printf("Vulkan device: %s\n", device.summary().c_str());
    // Where each buffer class lives (device/memory_policy.hpp): on a discrete GPU the classes the
    // shaders read must say DEVICE_LOCAL, and Readback HOST_CACHED.
    for (const std::string& line : describeMemoryPlacements())
        std::printf("Vulkan memory: %s\n", line.c_str());
    // A GPU driver that is installed but does not load leaves lavapipe as the device without a
    // word from the loader (the H100 machine without glvnd): say so.
    for (const IcdLoadFailure& f : findIcdLoadFailures(icdManifestFiles()))
        std::printf("Vulkan driver not loaded: %s (%s): %s\n", f.manifest.c_str(),
                    f.library.empty() ? "no library" : f.library.c_str(), f.reason.c_str());
    std::fflush(stdout);
    VulkanDeviceOptions deviceOptions;
    deviceOptions.validation = a.validation;
    NearRenderer near(deviceOptions);
    std::string csv = "scene,time,check,device,width,height,drawn_pixels,colour_diffs,depth_diffs,"
                      "id_diffs,result\n";
    int checks = 0, failed = 0;
    for (const std::string& file : a.scenes) {
        const Scene scene = loadScene(file);
        // The first frame and, for a camera path, the middle one (the camera has moved).
        std::vector<double> times = {0.0};
        if (scene.path) times.push_back(scene.timeOfFrame(scene.path->frameCount() / 2));
        for (double t : times) {
            const CameraFrame cam = makeCameraFrame(scene.cameraAt(t));
            const std::vector<SpriteSetup> sprites = setupSprites(scene, cam, t);
            Image reference(cam.width, cam.height, scene.render.background);
            renderReference(scene.models, sprites, reference);
            const Image vulkan =
                near.render(cam, scene.models, sprites, scene.render.background, NearOptions{});
            const ImageDiff d = diffImages(vulkan, reference);
            const std::size_t drawn = drawnPixels(reference);
            // A scene that draws nothing would pass for nothing.
            const bool ok = d.identical() && drawn > 0;
            ++checks;
            failed += ok ? 0 : 1;
            std::printf("%s t=%.3f: Vulkan near vs CPU reference: %zu colour, %zu depth, %zu id "
                        "pixels differ of %zu (%zu drawn): %s\n",
                        file.c_str(), t, d.colorDiffs, d.depthDiffs, d.idDiffs,
                        reference.pixelCount(), drawn,
                        ok ? "identical" : (drawn ? "DIFFERENT" : "NOTHING DRAWN"));
            std::fflush(stdout);
            char row[512];
            std::snprintf(row, sizeof row,
                          ",%.6f,near_vulkan_vs_reference,\"%s\",%d,%d,%zu,%zu,%zu,%zu,%s\n", t,
                          device.name.c_str(), cam.width, cam.height, drawn, d.colorDiffs,
                          d.depthDiffs, d.idDiffs, ok ? "identical" : "different");
            csv += file + row;
        }
    }
    if (a.validation && near.messageLog()->count() > 0) {
        std::printf("validation: %zu messages\n", near.messageLog()->count());
        ++failed;
    } else if (a.validation) {
        std::printf("validation: silent\n");
    }
    if (!a.csv.empty()) writeFileWhole(a.csv, csv);
    if (failed > 0)
        throw std::runtime_error(std::to_string(failed) + " of " + std::to_string(checks) +
                                 " checks failed");
    std::printf("%d of %d checks identical\n", checks, checks);
}

} // namespace

void addCheckCommand(CLI::App& app) {
    auto args = std::make_shared<CheckArgs>();
    CLI::App* cmd = app.add_subcommand(
        "check", "Check on this machine that the Vulkan near tier draws each scene exactly as "
                 "the CPU reference does (colour, depth, id; 0 differing pixels)");
    cmd->add_option("scenes", args->scenes, "Scene files (.json), e.g. scenes/golden/*.json")
        ->required()
        ->check(CLI::ExistingFile);
    cmd->add_option("--csv", args->csv, "Also write one CSV row per check");
    cmd->add_flag("--validation", args->validation,
                  "Run with the Vulkan validation layer (and synchronization validation); any "
                  "message fails the check");
    cmd->callback([args] { run(*args); });
}

} // namespace voxtier::cli
