// `voxtier render SCENE.json | MODEL.vox`: one frame to an image (PNG; EXR adds depth and ids).
#include "apps/commands.hpp"
#include "compose/frame.hpp"
#include "core/error.hpp"
#include "core/image_io.hpp"
#include "core/model_view.hpp"
#include "core/scene_loader.hpp"
#include "core/vox_reader.hpp"

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <optional>

namespace voxtier::cli {

namespace {

struct RenderArgs {
    std::string input;
    std::string out;
    std::string mode = "reference";
    std::optional<double> time;
    std::optional<int> frame;
    std::string ids;
    // MODEL.vox only
    std::string view = "30,20";
    double distance = 0.0;
    double sigma = 1.0;
    std::string size = "640x480";
    int model = 0;
};

bool endsWith(const std::string& s, const std::string& suffix) {
    if (s.size() < suffix.size()) return false;
    std::string tail = s.substr(s.size() - suffix.size());
    for (char& c : tail) c = char(std::tolower(c));
    return tail == suffix;
}

std::pair<double, double> parsePair(const std::string& text, char sep, const std::string& field) {
    const auto at = text.find(sep);
    try {
        if (at == std::string::npos) throw std::invalid_argument("");
        std::size_t used = 0;
        const double a = std::stod(text.substr(0, at), &used);
        const double b = std::stod(text.substr(at + 1), &used);
        if (!std::isfinite(a) || !std::isfinite(b)) throw std::invalid_argument("");
        return {a, b};
    } catch (const std::exception&) {
        throw InputError("", field, "expected two numbers separated by '" + std::string(1, sep) + "', got '" + text + "'");
    }
}

Scene loadInput(const RenderArgs& a) {
    if (!endsWith(a.input, ".vox")) return loadScene(a.input);
    const VoxFile vox = readVoxFile(a.input);
    if (a.model < 0 || a.model >= int(vox.models.size()))
        throw InputError(a.input, "--model", "file has " + std::to_string(vox.models.size()) + " models");
    auto model = std::make_shared<VoxelModel>(std::filesystem::path(a.input).stem().string(), vox.palette,
                                              std::vector<VoxelGrid>{vox.models[std::size_t(a.model)]});
    ModelView v;
    std::tie(v.azimuthDeg, v.elevationDeg) = parsePair(a.view, ',', "--view");
    const auto [w, h] = parsePair(a.size, 'x', "--size");
    if (w < 1 || h < 1 || w > Limits::kMaxImageDim || h > Limits::kMaxImageDim || w != std::floor(w) || h != std::floor(h))
        throw InputError("", "--size", "expected WxH with integers 1.." + std::to_string(Limits::kMaxImageDim));
    v.width = int(w);
    v.height = int(h);
    v.distance = a.distance;
    v.sigma = a.sigma;
    Scene s = sceneForModel(std::move(model), v);
    s.source = a.input;
    return s;
}

void run(const RenderArgs& a) {
    Scene scene = loadInput(a);
    const RenderMode mode = parseRenderMode(a.mode);
    int frame = 0;
    double time = 0.0;
    if (a.frame) {
        if (*a.frame < 0) throw InputError("", "--frame", "must be >= 0");
        frame = *a.frame;
        time = scene.timeOfFrame(frame);
    } else if (a.time) {
        time = *a.time;
        frame = scene.path ? int(std::floor((time - scene.path->keys.front().time) * scene.path->fps + 1e-9)) : 0;
    }
    FrameRenderer renderer(scene);
    renderer.applyEditsThrough(frame);
    const FrameResult r = renderer.render(time, mode);

    std::string out = a.out;
    if (out.empty()) out = "out/" + std::filesystem::path(a.input).stem().string() + ".png";
    writeImage(out, r.image, scene.cameraAt(time).zNear);
    if (!a.ids.empty()) writeIdImage(a.ids, r.image);
    std::size_t drawnPixels = 0;
    for (auto id : r.image.id) drawnPixels += id != kernel::VT_NO_ENTITY;
    if (mode == RenderMode::Near) std::printf("Vulkan device: %s\n", renderer.nearDeviceName().c_str());
    std::printf("%s: %s, t=%.3f s, %dx%d, %d entities (%d culled), %zu sprite pixels, %.1f ms -> %s\n",
                a.input.c_str(), toString(mode), time, r.image.width, r.image.height, r.stats.entities,
                r.stats.culled, drawnPixels, r.stats.totalMs, out.c_str());
}

} // namespace

void addRenderCommand(CLI::App& app) {
    auto args = std::make_shared<RenderArgs>();
    CLI::App* cmd = app.add_subcommand("render", "Render one frame of a scene (.json) or a single model (.vox)");
    cmd->add_option("input", args->input, "Scene file (.json) or MagicaVoxel model (.vox)")->required();
    cmd->add_option("-o,--out", args->out, "Output image (.png, or .exr with Z and id channels); default out/<name>.png");
    cmd->add_option("--mode", args->mode,
                    "reference (CPU reference tracer), near (Vulkan near tier; VOXTIER_VALIDATION=1 "
                    "enables validation) or far (every entity through the far tier's snapshot cache)")
        ->capture_default_str();
    auto* t = cmd->add_option("--time", args->time, "Time in seconds along the camera path");
    auto* f = cmd->add_option("--frame", args->frame, "Frame number of the camera path (applies scripted edits up to it)");
    t->excludes(f);
    cmd->add_option("--ids", args->ids, "Also write the entity-id buffer as a colour-coded PNG");
    auto* vox = cmd->add_option_group("single model (.vox input)");
    vox->add_option("--view", args->view, "AZIMUTH,ELEVATION in degrees")->capture_default_str();
    vox->add_option("--distance", args->distance, "Camera distance in metres (0 = fit)")->capture_default_str();
    vox->add_option("--sigma", args->sigma, "Virtual pixels per voxel")->capture_default_str();
    vox->add_option("--size", args->size, "Image size WxH")->capture_default_str();
    vox->add_option("--model", args->model, "Which model of a multi-model file")->capture_default_str();
    cmd->callback([args] { run(*args); });
}

} // namespace voxtier::cli
