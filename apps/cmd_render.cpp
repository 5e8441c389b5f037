// `voxtier render SCENE.json | MODEL.vox`: one frame to an image (PNG; EXR adds depth and ids).
#include "apps/cli_options.hpp"
#include "apps/commands.hpp"
#include "compose/frame.hpp"
#include "compose/frame_figures.hpp"
#include "core/error.hpp"
#include "core/image_io.hpp"
#include "core/model_view.hpp"
#include "core/scene_loader.hpp"
#include "core/vox_reader.hpp"

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <limits>
#include <optional>

namespace voxtier::cli {

namespace {

struct RenderArgs {
    std::string input;
    std::string out;
    RenderMode mode = RenderMode::Hybrid;
    NearBackend nearBackend = NearBackend::Vulkan;
    bool path = false;
    std::string overlay, csv, pops;
    std::optional<double> time;
    std::optional<int> frame;
    std::string ids;
    std::optional<double> cacheMb; ///< far snapshot cache budget; default FrameOptions'
    // Image size and sigma override a scene's; the rest describe the camera of a MODEL.vox render.
    std::optional<std::string> size; ///< WxH (imageSize()); default 640x480 for a .vox
    std::optional<double> sigma;     ///< default 1 for a .vox
    std::optional<std::string> view; ///< AZIMUTH,ELEVATION (viewAngles()); default 30,20
    std::optional<double> distance;  ///< default 0 (fit)
    std::optional<int> model;        ///< default 0
};

/// A budget the machine cannot hold would fail as an out-of-memory deep in a bake; a zero
/// budget would re-bake every far view every frame.
constexpr double kMaxCacheMb = 64 * 1024;

bool endsWith(const std::string& s, const std::string& suffix) {
    if (s.size() < suffix.size()) return false;
    std::string tail = s.substr(s.size() - suffix.size());
    for (char& c : tail) c = char(std::tolower(c));
    return tail == suffix;
}

/// The single-model options describe the camera of a .vox render; a scene brings its own camera
/// and names its models, so there they would be silently ignored.
void rejectSingleModelOptions(const RenderArgs& a) {
    const char* hasCamera = "applies to a .vox input only (a scene has its camera)";
    const char* namesModels = "applies to a .vox input only (a scene names its models)";
    if (a.view) throw CLI::ValidationError("--view", hasCamera);
    if (a.distance) throw CLI::ValidationError("--distance", hasCamera);
    if (a.model) throw CLI::ValidationError("--model", namesModels);
}

Scene loadInput(const RenderArgs& a) {
    // The option validators checked every value; what remains depends on the input file.
    if (!endsWith(a.input, ".vox")) {
        rejectSingleModelOptions(a);
        Scene s = loadScene(a.input);
        if (a.size) {
            const glm::ivec2 wh = *readImageSize(*a.size);
            s.camera.width = wh.x;
            s.camera.height = wh.y;
        }
        if (a.sigma) s.render.sigma = *a.sigma;
        return s;
    }
    const VoxFile vox = readVoxFile(a.input);
    const int index = a.model.value_or(0);
    if (index >= int(vox.models.size()))
        throw InputError(a.input, "--model",
                         "file has " + std::to_string(vox.models.size()) + " models");
    auto model =
        std::make_shared<VoxelModel>(std::filesystem::path(a.input).stem().string(), vox.palette,
                                     std::vector<VoxelGrid>{vox.models[std::size_t(index)]});
    ModelView v;
    const glm::dvec2 angles = *readViewAngles(a.view.value_or("30,20"));
    v.azimuthDeg = angles.x;
    v.elevationDeg = angles.y;
    const glm::ivec2 wh = *readImageSize(a.size.value_or("640x480"));
    v.width = wh.x;
    v.height = wh.y;
    v.distance = a.distance.value_or(0.0);
    v.sigma = a.sigma.value_or(1.0);
    Scene s = sceneForModel(std::move(model), v);
    s.source = a.input;
    return s;
}

std::string numbered(const std::string& pattern, int frame) {
    // out/x.png -> out/x_0007.png
    const std::filesystem::path p(pattern);
    char buf[32];
    std::snprintf(buf, sizeof buf, "_%04d", frame);
    return (p.parent_path() / (p.stem().string() + buf + p.extension().string())).string();
}

std::FILE* openCsv(const std::string& file, const char* header) {
    if (file.empty()) return nullptr;
    const std::filesystem::path p(file);
    if (p.has_parent_path()) std::filesystem::create_directories(p.parent_path());
    std::FILE* f = std::fopen(file.c_str(), "w");
    if (!f) throw InputError(file, "", "cannot open for writing");
    std::fputs(header, f);
    return f;
}

void run(const RenderArgs& a) {
    Scene scene = loadInput(a);
    const RenderMode mode = a.mode;
    FrameOptions opt;
    opt.nearBackend = a.nearBackend;
    opt.overlay = !a.overlay.empty();
    opt.measurePops = !a.pops.empty();
    if (a.cacheMb) opt.cacheBudgetBytes = std::size_t(*a.cacheMb * double(1 << 20));
    FrameRenderer renderer(scene, opt);
    std::string out = a.out;
    if (out.empty()) out = "out/" + std::filesystem::path(a.input).stem().string() + ".png";

    // Which frames: one (--time / --frame, default t = 0) or the whole camera path (--path).
    int first = 0, last = 0;
    std::optional<double> fixedTime;
    if (a.path) {
        if (!scene.path) throw InputError(a.input, "--path", "the scene has no camera_path");
        last = scene.path->frameCount() - 1;
    } else if (a.frame) {
        first = last = *a.frame;
    } else if (a.time) {
        fixedTime = *a.time;
        first = last =
            scene.path ? int(std::floor(
                             (*a.time - scene.path->keys.front().time) * scene.path->fps + 1e-9))
                       : 0;
        first = last = std::max(0, first);
    }
    std::FILE* csv = openCsv(a.csv, ("frame,time," + figureCsvHeader() + "\n").c_str());
    std::FILE* pops = openCsv(
        a.pops, "frame,entity,kind,changed_pixels,changed_fraction,displacement_px,radius_px\n");
    // A lone frame starts the selector fresh (tiers from the metric alone); --path runs the
    // frames in order, so hysteresis and cross-fades behave as in a game.
    for (int frame = first; frame <= last; ++frame) {
        const double time = fixedTime ? *fixedTime : scene.timeOfFrame(frame);
        renderer.applyEditsThrough(frame);
        const FrameResult r = renderer.render(time, mode, frame);
        const std::string file = a.path ? numbered(out, frame) : out;
        writeImage(file, r.image, scene.cameraAt(time).zNear);
        if (r.overlay) writeImage(a.path ? numbered(a.overlay, frame) : a.overlay, *r.overlay);
        if (!a.ids.empty()) writeIdImage(a.path ? numbered(a.ids, frame) : a.ids, r.image);
        const FrameStats& st = r.stats;
        if (csv) std::fprintf(csv, "%d,%.6f,%s\n", frame, time, figureCsvRow(st).c_str());
        for (const PopEvent& e : r.pops)
            std::fprintf(pops, "%d,%u,%s,%zu,%.6f,%.3f,%.3f\n", e.frame, e.entity, toString(e.kind),
                         e.changedPixels, e.changedFraction, e.displacementPx, e.radiusPx);
        if (frame == first && !renderer.nearDeviceName().empty())
            std::printf("Vulkan device: %s\n", renderer.nearDeviceName().c_str());
        std::printf("%s: %s, frame %d, t=%.3f s, %dx%d, %d entities (%d culled; %d near, %d far, "
                    "%d fading), "
                    "%d switches, %d bakes, worst predicted far displacement %.2f vpx, %.1f ms -> "
                    "%s\n",
                    a.input.c_str(), toString(mode), frame, time, r.image.width, r.image.height,
                    st.entities, st.culled, st.nearDrawn, st.farDrawn, st.fading,
                    st.switchesToFar + st.switchesToNear, st.farBakes, st.farPredictedWorstVpx,
                    st.totalMs, file.c_str());
    }
    if (csv) std::fclose(csv);
    if (pops) std::fclose(pops);
}

} // namespace

void addRenderCommand(CLI::App& app) {
    auto args = std::make_shared<RenderArgs>();
    CLI::App* cmd = app.add_subcommand(
        "render", "Render one frame of a scene (.json) or a single model (.vox)");
    cmd->add_option("input", args->input, "Scene file (.json) or MagicaVoxel model (.vox)")
        ->required()
        ->check(CLI::ExistingFile);
    cmd->add_option("-o,--out", args->out,
                    "Output image (.png, or .exr with Z and id channels); default out/<name>.png");
    cmd->add_option("--mode", args->mode,
                    "hybrid (the selector hands entities between the tiers), near (Vulkan near "
                    "tier for every entity; VOXTIER_VALIDATION=1 enables validation), far (every "
                    "entity through the snapshot cache) or reference (CPU reference tracer)")
        ->type_name("TEXT")
        ->transform(oneOf(kRenderModeNames, "render mode"))
        ->default_str(toString(args->mode));
    cmd->add_option("--near-backend", args->nearBackend,
                    "vulkan, or reference (the CPU tracer draws the near tier; same image)")
        ->type_name("TEXT")
        ->transform(oneOf(kNearBackendNames, "near backend"))
        ->default_str(toString(args->nearBackend));
    cmd->add_flag("--path", args->path,
                  "Render every frame of the camera path (OUT becomes OUT_0000.png ...)");
    cmd->add_option("--overlay", args->overlay,
                    "Also write the tier overlay (near blue, far orange, fading magenta)");
    cmd->add_option("--csv", args->csv, "Per-frame CSV: tier counts, switches, bakes, timings");
    cmd->add_option("--pops", args->pops,
                    "Per-switch CSV: the image change each tier/view switch causes alone");
    auto* t = cmd->add_option("--time", args->time, "Time in seconds along the camera path")
                  ->check(finite());
    auto* f = cmd->add_option("--frame", args->frame,
                              "Frame number of the camera path (applies scripted edits up to it)")
                  ->check(atLeast(0));
    t->excludes(f);
    cmd->add_option("--cache-mb", args->cacheMb,
                    "Far snapshot cache budget in MiB (default 256; LRU beyond)")
        ->check(numberIn(1, kMaxCacheMb, "MiB"));
    cmd->add_option("--ids", args->ids, "Also write the entity-id buffer as a colour-coded PNG");
    cmd->add_option("--size", args->size,
                    "Image size (default: the scene's camera; 640x480 for a .vox)")
        ->type_name("WxH")
        ->check(imageSize());
    cmd->add_option("--sigma", args->sigma,
                    "Virtual pixels per voxel (default: the scene's; 1 for a .vox)")
        ->check(sigmaRange());
    auto* vox = cmd->add_option_group("single model (.vox input)");
    vox->add_option("--view", args->view, "Camera direction in degrees (default 30,20)")
        ->type_name("AZIMUTH,ELEVATION")
        ->check(viewAngles());
    vox->add_option("--distance", args->distance, "Camera distance in metres (default 0 = fit)")
        ->check(numberIn(0, std::numeric_limits<double>::infinity(), "m"));
    vox->add_option("--model", args->model, "Which model of a multi-model file (default 0)")
        ->check(atLeast(0));
    cmd->callback([args] { run(*args); });
}

} // namespace voxtier::cli
