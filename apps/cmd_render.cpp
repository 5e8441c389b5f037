// `voxtier render SCENE.json | MODEL.vox`: one frame to an image (PNG; EXR adds depth and ids).
#include "apps/cache_dir_options.hpp"
#include "apps/cli_options.hpp"
#include "apps/commands.hpp"
#include "apps/progress.hpp"
#include "compose/frame.hpp"
#include "compose/frame_figures.hpp"
#include "compose/pop_measure.hpp"
#include "compose/scene_render.hpp"
#include "core/error.hpp"
#include "core/file_write.hpp"
#include "core/model_view.hpp"
#include "core/scene_loader.hpp"
#include "core/sprite.hpp"
#include "core/stopwatch.hpp"
#include "core/vox_reader.hpp"
#include "image_files/image_files.hpp"
#include "impostor_cache/snapshot_cache.hpp"

#include <algorithm>
#include <cctype>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <functional>
#include <future>
#include <limits>
#include <optional>
#include <vector>

namespace voxtier::cli {

namespace {

struct RenderArgs {
    std::string input;
    std::string out;
    RenderMode mode = RenderMode::Hybrid;
    bool modeGiven = false; ///< --mode on the command line (else a .vox preview is exact)
    /// How the frames are drawn: what the command line sets of it (--near-backend and the flags
    /// render shares with bench, addFrameFlags); run() adds the rest.
    FrameOptions drawing;
    bool path = false;
    bool alpha = false; ///< transparent background (alpha 0 where no sprite is drawn)
    std::string overlay, csv, pops;
    std::optional<int> popThreshold; ///< pixels of what is seen (PopSummary); measures pops
    std::optional<double> time;
    std::optional<int> frame;
    std::optional<std::string> frames; ///< FIRST:LAST[:STEP] (readFrameRange)
    std::string ids;
    std::optional<double> cacheMb; ///< far snapshot cache budget; default FrameOptions'
    CacheDirArgs cacheDir;
    // Image size and sigma override a scene's; the rest describe the camera of a MODEL.vox render.
    std::optional<std::string> size; ///< WxH (imageSize()); default 640x480 for a .vox
    std::optional<double> sigma;     ///< default 1 for a .vox
    std::optional<std::string> view; ///< AZIMUTH,ELEVATION (viewAngles()); default 30,20
    std::optional<double> distance;  ///< default 0 (fit)
    std::optional<int> model;        ///< default 0
};

/// A switch that changes more pixels than this of what is seen counts as visible in the pops
/// summary, unless --pop-threshold says otherwise: about a 4x4 block, a few virtual pixels of a
/// sprite at sigma 1.
constexpr int kDefaultPopThresholdPx = 16;

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

/// A .vox has no camera path and no animation clock: frame options would be silently ignored.
void rejectPathOptions(const RenderArgs& a) {
    const char* why = "applies to a scene input only (a .vox has no camera path or animation "
                      "clock; --view and --distance place its camera)";
    if (a.frame) throw CLI::ValidationError("--frame", why);
    if (a.time) throw CLI::ValidationError("--time", why);
    if (a.frames) throw CLI::ValidationError("--frames", why);
    if (a.path) throw CLI::ValidationError("--path", why);
}

/// A --distance that puts the camera inside an entity's proxy box would draw nothing there.
void rejectCameraInside(const RenderArgs& a, const Scene& s) {
    if (!a.distance) return;
    const std::vector<SpriteSetup> sprites = setupSprites(s, makeCameraFrame(s.camera), 0.0);
    for (const SpriteSetup& sp : sprites)
        if (sp.cull == CullReason::CameraInside) {
            char at[32];
            std::snprintf(at, sizeof at, "%g", *a.distance);
            throw InputError(a.input, "--distance",
                             std::string("at ") + at +
                                 " m the camera is inside the model's box and would draw "
                                 "nothing; use a larger distance, or 0 to fit the view");
        }
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
        if (a.alpha) s.render.background &= 0x00FFFFFFu;
        return s;
    }
    rejectPathOptions(a);
    const VoxFile vox = readVoxFile(a.input);
    ModelView v;
    const glm::dvec2 angles = *readViewAngles(a.view.value_or("30,20"));
    v.azimuthDeg = angles.x;
    v.elevationDeg = angles.y;
    const glm::ivec2 wh = *readImageSize(a.size.value_or("640x480"));
    v.width = wh.x;
    v.height = wh.y;
    v.distance = a.distance.value_or(0.0);
    v.sigma = a.sigma.value_or(1.0);
    Scene s;
    // A file of several models placed by a scene graph is a scene: render it whole, as a
    // scene's "vox_scenes" does, unless --model picks one.
    if (!a.model && vox.models.size() > 1 && !vox.instances.empty()) {
        s = sceneForVoxFile(vox, v);
    } else {
        const int index = a.model.value_or(0);
        if (index >= int(vox.models.size()))
            throw InputError(a.input, "--model",
                             "file has " + std::to_string(vox.models.size()) + " models");
        s = sceneForModel(std::make_shared<VoxelModel>(
                              std::filesystem::path(a.input).stem().string(), vox.palette,
                              std::vector<VoxelGrid>{vox.models[std::size_t(index)]}),
                          v);
    }
    s.source = a.input;
    if (a.alpha) s.render.background &= 0x00FFFFFFu;
    rejectCameraInside(a, s);
    return s;
}

std::string numbered(const std::string& pattern, int frame) {
    // out/x.png -> out/x_0007.png
    const std::filesystem::path p(pattern);
    char buf[32];
    std::snprintf(buf, sizeof buf, "_%04d", frame);
    return (p.parent_path() / (p.stem().string() + buf + p.extension().string())).string();
}

/// The files a render writes, by option: no two may be one file (the later write would replace
/// the earlier one without a word), and none may be the input. Numbered sequences share their
/// pattern's rule, so comparing the patterns covers every frame.
void rejectCollidingOutputs(const RenderArgs& a, const std::string& out, const std::string& idKey) {
    const std::pair<const char*, const std::string*> outputs[] = {
        {"--out", &out},   {"--overlay", &a.overlay}, {"--ids", &a.ids},
        {"--csv", &a.csv}, {"--pops", &a.pops},       {"--ids (its key)", &idKey}};
    for (std::size_t i = 0; i < std::size(outputs); ++i) {
        if (outputs[i].second->empty()) continue;
        if (sameOutputFile(*outputs[i].second, a.input))
            throw CLI::ValidationError(outputs[i].first, *outputs[i].second + " is the input file");
        for (std::size_t j = 0; j < i; ++j)
            if (!outputs[j].second->empty() &&
                sameOutputFile(*outputs[i].second, *outputs[j].second))
                throw CLI::ValidationError(outputs[i].first,
                                           *outputs[i].second + " is also " + outputs[j].first +
                                               "'s file; each output needs its own");
    }
}

/// Which frames one render writes.
struct FramePlan {
    std::vector<int> frames;                ///< path frames, in render order
    std::optional<double> fixedTime;        ///< --time: this time instead of the frame's
    bool sequence = false;                  ///< --path / --frames: numbered images, progress
    int step = 1;                           ///< frames apart
    SceneCamera camera = SceneCamera::Path; ///< Still: a plain render (compose/scene_render.hpp)
};

/// The last frame of the scene's camera path, or a frame past it is an error naming `option`.
void checkPathFrame(const RenderArgs& a, const Scene& scene, const char* option, int frame) {
    if (scene.path && frame >= scene.path->frameCount())
        throw InputError(a.input, option,
                         "frame " + std::to_string(frame) +
                             " is past the camera path's last frame " +
                             std::to_string(scene.path->frameCount() - 1));
}

/// The longest animation time --time takes without a camera path: 11.6 days, far past any
/// animation loop, so no real use is refused, while a typo such as 1e308 is not taken silently.
constexpr double kMaxAnimationTime = 1e6;

/// --time inside the camera path's keys (or in [0, kMaxAnimationTime] without a path), else an
/// error naming --time, as --frame past the path's last frame is.
void checkPathTime(const RenderArgs& a, const Scene& scene, double t) {
    const double lo = scene.path ? scene.path->keys.front().time : 0.0;
    const double hi = scene.path ? scene.path->keys.back().time : kMaxAnimationTime;
    if (t >= lo && t <= hi) return;
    char msg[160];
    if (scene.path)
        std::snprintf(msg, sizeof msg, "t=%g s is %s the camera path's %s at %g s", t,
                      t < lo ? "before" : "past", t < lo ? "first key" : "last key",
                      t < lo ? lo : hi);
    else
        std::snprintf(msg, sizeof msg, "t=%g s is outside [0, %g] s (the scene has no camera path)",
                      t, hi);
    throw InputError(a.input, "--time", msg);
}

/// The camera rule (docs/scenes.md "Which camera a render uses"; applyCameraRule): --path,
/// --frames, --frame and --time follow the camera path; a plain render is a still.
FramePlan planFrames(const RenderArgs& a, const Scene& scene) {
    FramePlan p;
    if (a.path || a.frames) {
        FrameRange r;
        if (a.path) {
            if (!scene.path) throw InputError(a.input, "--path", "the scene has no camera_path");
            r.last = scene.path->frameCount() - 1;
        } else {
            r = *readFrameRange(*a.frames);
            checkPathFrame(a, scene, "--frames", r.last);
        }
        for (int f = r.first; f <= r.last; f += r.step) p.frames.push_back(f);
        p.sequence = true;
        p.step = r.step;
    } else if (a.frame) {
        checkPathFrame(a, scene, "--frame", *a.frame);
        p.frames = {*a.frame};
    } else if (a.time) {
        checkPathTime(a, scene, *a.time);
        p.fixedTime = *a.time;
        p.frames = {frameAtTime(scene, *a.time)};
    } else {
        p.camera = SceneCamera::Still;
        p.frames = {0};
    }
    return p;
}

/// " [k/N, ~S s left]" after frame k of a sequence, from the mean time per frame so far.
std::string progress(const FramePlan& plan, std::size_t done, double elapsedMs) {
    if (!plan.sequence) return "";
    const double left = elapsedMs / double(done) * double(plan.frames.size() - done) / 1000.0;
    char buf[64];
    std::snprintf(buf, sizeof buf, " [%zu/%zu, ~%.0f s left]", done, plan.frames.size(), left);
    return buf;
}

/// What a frame's status line says it cost, apart: the frame itself (FrameStats::totalMs, the
/// --csv frame_ms), measuring its pops, and writing (or, into a GIF, encoding) its files.
struct FrameTimes {
    double frameMs = 0.0;
    std::optional<double> popsMs;
    double writeMs = 0.0;
    bool encoding = false; ///< a GIF's frame: encoded now, written with the last
};

/// ", 3 bakes" with, where an edit made snapshots stale, how many of them refreshed those.
std::string bakesText(const FrameStats& st) {
    std::string s = std::to_string(st.far.bakes) + (st.far.bakes == 1 ? " bake" : " bakes");
    if (st.far.refreshes > 0)
        s += " (" + std::to_string(st.far.refreshes) + " after an edit made " +
             (st.far.refreshes == 1 ? "a snapshot" : "snapshots") + " stale)";
    return s;
}

/// The one console line per frame.
void printStatus(const RenderArgs& a, RenderMode mode, int frame, double time, const FrameResult& r,
                 const FrameTimes& times, const std::string& file,
                 const std::string& progressText) {
    const FrameStats& st = r.stats;
    // Each visible entity once: a cross-fading one is drawn by both tiers but counted as fading.
    int nearOnly = 0, farOnly = 0, fading = 0;
    for (std::size_t i = 0; i < r.plan.size(); ++i) {
        if (!r.sprites[i].visible()) continue;
        if (r.plan[i].fade > 0.0f)
            ++fading;
        else
            ++(r.plan[i].tier == Tier::Near ? nearOnly : farOnly);
    }
    char pops[48] = "";
    if (times.popsMs) std::snprintf(pops, sizeof pops, ", pops %.1f ms", *times.popsMs);
    std::printf("%s: %s, frame %d, t=%.3f s, %dx%d, %d entities (%d culled; %d near, %d far, "
                "%d fading%s%s), "
                "%d switches, %s, worst predicted far displacement %.2f vpx, frame %.1f ms%s, "
                "%s %.1f ms -> %s%s\n",
                a.input.c_str(), toString(mode), frame, time, r.image.width, r.image.height,
                st.entities, st.culled, nearOnly, farOnly, fading,
                st.nearDrawn == 0 ? ""
                : st.nearOnVulkan ? "; near tier on Vulkan"
                                  : "; near tier on the CPU reference",
                st.farDrawn == 0 ? ""
                : st.farOnVulkan ? "; far tier on Vulkan"
                                 : "; far tier on the CPU blit",
                st.plan.switchesToFar + st.plan.switchesToNear, bakesText(st).c_str(),
                st.plan.worstVpx, times.frameMs, pops, times.encoding ? "encoding" : "writing",
                times.writeMs, file.c_str(), progressText.c_str());
    std::fflush(stdout);
}

/// Far sprites drawn from a snapshot whose predicted silhouette displacement (CONTRACT.md §5) is
/// over 1 virtual pixel: where the image is visibly approximate. The plan counts them
/// (PlanStats::farOverOneVpx) from the predictions it made anyway.
struct Approximation {
    std::size_t sprites = 0; ///< far sprite draws over 1 vpx, all frames together
    double worstVpx = 0.0;

    void add(const FrameResult& r) {
        const PlanStats& plan = r.stats.plan;
        if (plan.farOverOneVpx == 0) return;
        sprites += std::size_t(plan.farOverOneVpx);
        // Some far sprite is over 1 vpx, so the frame's worst is the worst of those.
        worstVpx = std::max(worstVpx, plan.worstVpx);
    }
};

/// Frames that show no entity at all, and why the first of them does: an empty image would
/// otherwise give no hint (an entity behind the camera, off screen, under half a pixel).
struct EmptyFrames {
    std::size_t frames = 0;
    int first = 0;
    std::string why; ///< the first one's

    void add(int frame, const FrameResult& r) {
        for (const SpriteSetup& s : r.sprites)
            if (s.visible()) return;
        if (frames++ > 0) return;
        first = frame;
        const std::size_t n = r.sprites.size();
        if (n == 0) {
            why = "the scene has no entities";
            return;
        }
        why = "of " + std::to_string(n) + (n == 1 ? " entity: " : " entities: ");
        const std::pair<CullReason, const char*> reasons[] = {
            {CullReason::BehindCamera, "behind the camera"},
            {CullReason::OffScreen, "off screen"},
            {CullReason::SubPixel, "sub-pixel (under half a pixel across)"},
            {CullReason::CameraInside, "around the camera (the eye inside its box)"},
        };
        bool firstReason = true;
        for (const auto& [reason, text] : reasons) {
            const auto count =
                std::count_if(r.sprites.begin(), r.sprites.end(),
                              [&](const SpriteSetup& s) { return s.cull == reason; });
            if (count == 0) continue;
            why += (firstReason ? "" : ", ") + std::to_string(count) + " " + text;
            firstReason = false;
        }
    }
    /// The one warning line ("" when every frame showed an entity).
    std::string line(std::size_t framesRendered) const {
        if (frames == 0) return "";
        const std::string hint = "; check the camera's position and target and the entities' "
                                 "positions";
        if (framesRendered == 1) return "the image shows no entity (" + why + ")" + hint;
        return std::to_string(frames) + " of " + std::to_string(framesRendered) +
               " frames show no entity (the first, frame " + std::to_string(first) + ", " + why +
               ")" + hint;
    }
};

/// The key of the --ids image beside it: out/ids.png -> out/ids_key.csv (one for a sequence).
std::string idKeyFile(const std::string& ids) {
    const std::filesystem::path p(ids);
    return (p.parent_path() / (p.stem().string() + "_key.csv")).string();
}

/// A CSV field: quoted where it holds a comma, a quote or a line break.
std::string csvField(const std::string& text) {
    if (text.find_first_of(",\"\n\r") == std::string::npos) return text;
    std::string q = "\"";
    for (char c : text) q += c == '"' ? std::string("\"\"") : std::string(1, c);
    return q + "\"";
}

/// The key from the --ids image's colours to entities: one row per entity the images show.
std::string idKey(const Scene& scene, const std::vector<bool>& shown) {
    std::string csv = "entity,name,model,r,g,b\n";
    for (std::size_t i = 0; i < shown.size(); ++i) {
        if (!shown[i]) continue;
        const Entity& e = scene.entities[i];
        const Rgba8 c = idColor(std::uint32_t(i));
        csv += std::to_string(i) + "," + csvField(e.name) + "," +
               csvField(scene.models.at(std::size_t(e.model))->name()) + "," +
               std::to_string(channel(c, 0)) + "," + std::to_string(channel(c, 1)) + "," +
               std::to_string(channel(c, 2)) + "\n";
    }
    return csv;
}

/// The pops summary line: how many switches, the worst seen change, how many over the threshold.
std::string popSummaryLine(const PopSummary& s, std::size_t frames) {
    char buf[512];
    std::snprintf(buf, sizeof buf,
                  "pops: %zu switches in %zu frames (%zu tier, %zu view, %zu cross-fade steps), "
                  "%zu changed what is seen",
                  s.events, frames, s.tierSwitches, s.viewSwitches, s.fadeSteps, s.seen);
    std::string line = buf;
    if (s.seen > 0) {
        std::snprintf(buf, sizeof buf, "; worst seen: %zu px changed (entity %u, frame %d)",
                      s.worstPixels, s.worstPixelsEvent.entity, s.worstPixelsEvent.frame);
        line += buf;
        if (s.worstVpx > 0.0)
            std::snprintf(buf, sizeof buf, ", silhouette moved %.2f vpx (entity %u, frame %d)",
                          s.worstVpx, s.worstVpxEvent.entity, s.worstVpxEvent.frame);
        else
            std::snprintf(buf, sizeof buf, ", no silhouette moved");
        line += buf;
    }
    if (s.appearing > 0)
        line += "; " + std::to_string(s.appearing) + " made an entity appear or vanish";
    std::snprintf(buf, sizeof buf, "; %zu over %zu px seen (--pop-threshold)", s.overThreshold,
                  s.thresholdPx);
    return line + buf;
}

/// A file that cannot hold an alpha channel: --alpha would be dropped without a word.
void rejectAlphaFormat(const RenderArgs& a, const std::string& out) {
    if (!a.alpha) return;
    for (const char* ext : {".gif", ".jpg", ".jpeg"})
        if (endsWith(out, ext))
            throw CLI::ValidationError("--alpha", std::string("a ") + ext +
                                                      " file cannot hold the transparency; write "
                                                      ".png, .exr or .tif");
}

/// An id image whose colours are not kept exactly: its key could not name each pixel's entity.
void rejectLossyIdFormat(const RenderArgs& a) {
    for (const char* ext : {".gif", ".jpg", ".jpeg"})
        if (!a.ids.empty() && endsWith(a.ids, ext))
            throw CLI::ValidationError("--ids", std::string("a ") + ext +
                                                    " file does not keep every entity's colour "
                                                    "(GIF holds 256, JPEG is lossy), so its key "
                                                    "could not name each pixel's entity; write "
                                                    ".png, .exr, .tif or .pam");
}

void run(const RenderArgs& a) {
    const auto runStart = std::chrono::steady_clock::now();
    Scene input = loadInput(a);
    const FramePlan plan = planFrames(a, input);
    FrameOptions opt = a.drawing;
    // The CPU reference's rows, for the progress line of a lone long frame.
    WorkProgress nearRows;
    opt.nearProgress = &nearRows;
    opt.overlay = !a.overlay.empty();
    opt.measurePops = !a.pops.empty() || a.popThreshold;
    if (a.cacheMb) opt.cacheBudgetBytes = std::size_t(*a.cacheMb * double(1 << 20));
    opt.cacheDir = a.cacheDir.dir;
    opt.cacheDirBytes = a.cacheDir.limitBytes();
    std::string out = a.out;
    if (out.empty())
        out = "out/" + std::filesystem::path(a.input).stem().string() + defaultImageExtension();
    rejectCollidingOutputs(a, out, a.ids.empty() ? "" : idKeyFile(a.ids));
    rejectAlphaFormat(a, out);
    rejectLossyIdFormat(a);
    // A build without OpenImageIO writes .pam alone: say so before rendering, not after.
    for (const std::string& f : {a.overlay, a.ids})
        if (!f.empty() && !canWriteImageFormat(f)) throw InputError(f, "", imageFormatRefusal(f));
    // Depth and ids leave the GPU only for output that has them (EXR, --ids) or reads them.
    opt.depthAndIds =
        lowerExtension(out) == ".exr" || !a.ids.empty() || opt.overlay || opt.measurePops;
    SceneRenderer sceneRenderer(std::move(input), plan.camera, opt);
    const Scene& scene = sceneRenderer.scene();
    FrameRenderer& renderer = sceneRenderer.frames();
    // A .vox render is a preview, where a user judges the model (or the file's scene graph):
    // without --mode it is drawn exactly, by the near tier (Vulkan on a GPU, else the CPU
    // reference: the same pixels, tests/vulkan_identity_test.cpp), never from a far snapshot.
    RenderMode mode = a.mode;
    const bool exactPreview = endsWith(a.input, ".vox") && !a.modeGiven;
    if (exactPreview)
        mode = renderer.nearBackend() == NearBackend::Vulkan ? RenderMode::Near
                                                             : RenderMode::Reference;

    // The CSVs are kept in memory and written whole after the last frame (core/file_write.hpp).
    std::string csv = "frame,time," + figureCsvHeader() + "\n";
    std::string pops = popCsvHeader() + "\n";
    PopSummary popSummary(std::size_t(a.popThreshold.value_or(kDefaultPopThresholdPx)));
    EmptyFrames empty;
    std::vector<bool> idsShown(scene.entities.size(), false);
    char row[512];
    // A lone frame starts the selector fresh (tiers from the metric alone); a sequence runs its
    // frames in order, so hysteresis and cross-fades behave as in a game.
    // A sequence to .gif is one animated GIF at the path's frame rate (per rendered frame); a
    // lone frame, a still one. Either way the encoder says which frames it could not hold.
    std::optional<AnimationWriter> animation;
    if (endsWith(out, ".gif"))
        animation.emplace(out, (scene.path ? scene.path->fps : 30.0) / plan.step);
    const auto start = std::chrono::steady_clock::now();
    bool choiceSaid = false, farChoiceSaid = false;
    Approximation approx;
    std::optional<Progress> progressLine(std::in_place,
                                         plan.frames.size() == 1 ? "frame" : "frames",
                                         plan.frames.size(), &nearRows, "sprite rows");
    // A sequence keeps frames in flight: frame k+1 is submitted (set-up, selection, bakes, and a
    // frame wholly on Vulkan recorded and on the device) before frame k is finished (read back),
    // and frame k's files are written on a worker thread while frame k+2 is drawn or recorded
    // and frame k+1 finishes: the writer starts once frame k+2 is set up and selected (submit's
    // `selected`), so that it shares the cores with drawing and waiting, not with the set-up and
    // selection. Started as soon as frame k was finished, it ran beside frame k+2's set-up, which
    // took 1-4 ms longer for it (100,000 moving tanks on two cores writing .pam: 10-11.4 ms
    // against 7.5-9.3). Pops are measured with the scene's models as frame k drew them, so they
    // run one frame at a time.
    const bool overlap = plan.sequence && !opt.measurePops;
    const auto submitFrame = [&](std::size_t k, const std::function<void()>& selected = {}) {
        const int frame = plan.frames[k];
        return plan.fixedTime ? sceneRenderer.submitAt(*plan.fixedTime, mode, selected)
                              : sceneRenderer.submit(frame, mode, selected);
    };
    /// A finished frame whose files are being written.
    struct Writing {
        std::size_t k = 0;
        int frame = 0;
        double time = 0.0;
        FrameResult result;
        FrameTimes times;
        std::string file;
        std::function<void()> write; ///< the files' job, until it is started
        std::future<void> done;
    };
    std::optional<Writing> writing;
    const auto startWriting = [&](Writing& w) {
        if (!w.done.valid())
            w.done = std::async(overlap ? std::launch::async : std::launch::deferred,
                                std::move(w.write));
    };
    // Waits for the frame's files, names the frame if they failed, then prints its status line.
    const auto finishWriting = [&](Writing& w) {
        try {
            startWriting(w);
            w.done.get();
        } catch (const InputError& e) {
            if (!plan.sequence) throw;
            // Which frame, and what stands: the earlier numbered frames (each written whole),
            // never a GIF (written only whole, after the last frame).
            const std::string kept =
                animation ? out + " is not written"
                          : "the " + std::to_string(w.k) + " frames before it are written";
            throw InputError(e.file(), e.field(),
                             e.reason() + " (frame " + std::to_string(w.frame) + "; " + kept + ")");
        }
        progressLine->note("");
        progressLine->clear();
        printStatus(a, mode, w.frame, w.time, w.result, w.times, w.file,
                    progress(plan, w.k + 1, msSince(start)));
        progressLine->done(w.k + 1);
    };
    FrameRenderer::PendingFrame pending = submitFrame(0);
    for (std::size_t k = 0; k < plan.frames.size(); ++k) {
        const int frame = plan.frames[k];
        const double time = plan.fixedTime ? *plan.fixedTime : scene.timeOfFrame(frame);
        nearRows.reset();
        const auto renderStart = std::chrono::steady_clock::now();
        FrameRenderer::PendingFrame next;
        if (overlap && k + 1 < plan.frames.size())
            next = submitFrame(k + 1, [&] {
                if (writing) startWriting(*writing);
            });
        if (writing) startWriting(*writing);
        FrameResult r = renderer.finish(std::move(pending));
        FrameTimes times;
        times.frameMs = r.stats.totalMs;
        // Measuring pops is the time render() takes past the frame's own.
        if (opt.measurePops) times.popsMs = std::max(0.0, msSince(renderStart) - r.stats.totalMs);
        approx.add(r);
        empty.add(frame, r);
        csv += std::to_string(frame) + ",";
        std::snprintf(row, sizeof row, "%.6f,", time);
        csv += row + figureCsvRow(figuresOf(r.stats)) + "\n";
        for (const PopEvent& e : r.pops) {
            pops += popCsvRow(e) + "\n";
            popSummary.add(e);
        }
        if (!a.ids.empty())
            for (const std::uint32_t id : r.image.id)
                if (id < idsShown.size()) idsShown[id] = true;
        if (k == 0 && !renderer.nearDeviceName().empty())
            std::printf("Vulkan device: %s\n", renderer.nearDeviceName().c_str());
        // Auto's choice, once, when a frame drew near sprites: which backend and why.
        if (!choiceSaid && r.stats.nearDrawn > 0 && !renderer.nearBackendChoice().empty() &&
            (exactPreview || (mode != RenderMode::Near && mode != RenderMode::Reference))) {
            std::printf("%s\n", renderer.nearBackendChoice().c_str());
            choiceSaid = true;
        }
        if (!farChoiceSaid && r.stats.farDrawn > 0 && !renderer.farBackendChoice().empty()) {
            std::printf("%s\n", renderer.farBackendChoice().c_str());
            farChoiceSaid = true;
        }
        // The previous frame's files first (one write at a time, in order), then this frame's.
        if (writing) finishWriting(*writing);
        const auto name = [&](const std::string& f) {
            return plan.sequence ? numbered(f, frame) : f;
        };
        writing.emplace(
            Writing{k, frame, time, std::move(r), times, animation ? out : name(out), {}, {}});
        writing->times.encoding = animation.has_value();
        // The job reads the frame through `writing`, which stays put until it is finished.
        const auto write = [&, job = &*writing, overlay = name(a.overlay), ids = name(a.ids),
                            zNear = scene.cameraAt(time).zNear] {
            const auto writeStart = std::chrono::steady_clock::now();
            if (animation)
                animation->add(job->result.image);
            else
                writeImage(job->file, job->result.image, zNear);
            if (job->result.overlay) writeImage(overlay, *job->result.overlay);
            if (!a.ids.empty()) writeIdImage(ids, job->result.image);
            job->times.writeMs = msSince(writeStart);
        };
        writing->write = write;
        if (!overlap) finishWriting(*writing), writing.reset();
        pending = next                         ? std::move(next)
                  : k + 1 < plan.frames.size() ? submitFrame(k + 1)
                                               : FrameRenderer::PendingFrame();
    }
    if (writing) finishWriting(*writing), writing.reset();
    progressLine.reset();
    if (animation) animation->close();
    if (!a.csv.empty()) writeFileWhole(a.csv, csv);
    if (!a.pops.empty()) writeFileWhole(a.pops, pops);
    if (!a.ids.empty()) writeFileWhole(idKeyFile(a.ids), idKey(scene, idsShown));
    if (opt.measurePops)
        std::printf("%s\n", popSummaryLine(popSummary, plan.frames.size()).c_str());
    if (plan.sequence)
        std::printf("%zu frames in %.1f s (wall time: loading, rendering and writing) -> %s\n",
                    plan.frames.size(), msSince(runStart) / 1000.0,
                    animation ? out.c_str() : numbered(out, plan.frames.front()).c_str());
    if (animation) {
        const std::string note = gifFidelityNote(out, animation->fidelity());
        if (!note.empty()) std::fprintf(stderr, "voxtier: warning: %s\n", note.c_str());
    }
    if (const std::string line = empty.line(plan.frames.size()); !line.empty())
        std::fprintf(stderr, "voxtier: warning: %s\n", line.c_str());
    if (approx.sprites > 0)
        std::fprintf(stderr,
                     "voxtier: warning: %zu far sprite%s drawn from snapshots predicted to be off "
                     "by over 1 virtual pixel (worst %.2f vpx): the image is approximate there; "
                     "--mode near or --mode reference draws every entity exactly\n",
                     approx.sprites, approx.sprites == 1 ? "" : "s", approx.worstVpx);
    if (const auto& store = renderer.snapshotCache().config().store) {
        store->flush(); // what is still buffered, so that the summary counts every write
        const SnapshotStoreCounters c = store->counters();
        std::printf("%s\n", cacheDirSummary(store->options(), c).c_str());
        // The image does not depend on the cache, so failed writes do not fail the render; one
        // line says they happened and why (the store itself does not warn per file).
        if (c.writeFailures > 0)
            std::fprintf(stderr, "%s\n", cacheDirWriteWarning(store->options(), c).c_str());
    }
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
                    "Output image by extension: .png, .exr (linear colour with Z and id "
                    "channels), .tif, .jpg (no alpha), .gif (no alpha; exact up to 256 colours a "
                    "frame; with --path or --frames: one animated GIF), .pam (RGBA); .pam and "
                    ".gif need no image library, the formats of a build without OpenImageIO; "
                    "default out/<name>.png (.pam there)")
        ->check(imageFileName());
    auto* modeOption = addChoiceOption(
        *cmd, "--mode", args->mode, kRenderModeNames, "render mode",
        "hybrid (the selector hands entities between the tiers), near (Vulkan near tier for "
        "every entity; VOXTIER_VALIDATION=1 enables validation), far (every entity through the "
        "snapshot cache) or reference (CPU reference tracer). Default: hybrid for a scene; a "
        ".vox preview is drawn exactly, by the near tier (near on a GPU, else reference)");
    addChoiceOption(*cmd, "--near-backend", args->drawing.nearBackend, kNearBackendNames,
                    "near backend",
                    "auto (Vulkan on a GPU; the CPU reference where the only Vulkan device is a "
                    "CPU, as lavapipe is, or there is none), vulkan, or reference; same image");
    // The cost bound learns a bake's cost from measured times, so under another load a run may
    // draw an entity near where another drew it far: a comparison of images needs it off.
    addFrameFlags(*cmd, args->drawing,
                  {.farBackend = "auto (the Vulkan far pass on a GPU with shaderFloat64; the CPU "
                                 "blit where the only Vulkan device is a CPU, as lavapipe is, or "
                                 "there is none), vulkan, or cpu; same image",
                   .costBound = "Error-budget scenes: bound bakes only by max_bakes_per_frame, not "
                                "by the costs measured on earlier frames, so that the image does "
                                "not depend on the machine's load (for comparing images)"});
    auto* path =
        cmd->add_flag("--path", args->path,
                      "Render every frame of the camera path (OUT becomes OUT_0000.png ...; "
                      "OUT.gif: one animated GIF at the path's frame rate)");
    cmd->add_flag("--alpha", args->alpha,
                  "Transparent background: alpha 0 where no sprite is drawn (PNG, EXR, TIFF; "
                  "like a scene background [r, g, b, 0]); an error with .gif and .jpg");
    cmd->add_option("--overlay", args->overlay,
                    "Also write the tier overlay (near blue, far orange, cross-fading green; "
                    "with a legend)");
    cmd->add_option("--csv", args->csv,
                    "Per-frame CSV: tier counts, switches, bakes, timings (columns: "
                    "docs/outputs.md)");
    cmd->add_option("--pops", args->pops,
                    "Per-switch CSV: what each tier or view switch changes, the entity alone and "
                    "in the frame as seen, occlusion included (columns: docs/outputs.md); prints "
                    "a pops summary line");
    cmd->add_option("--pop-threshold", args->popThreshold,
                    "Pixels of the seen image a switch may change before the pops summary counts "
                    "it as visible (default " +
                        std::to_string(kDefaultPopThresholdPx) +
                        "); measures pops and prints the summary, with or without --pops")
        ->type_name("PX")
        ->check(atLeast(0));
    auto* t =
        cmd->add_option("--time", args->time,
                        "Time in seconds along the camera path, within its keys (without one: "
                        "the animation time in [0, 1e6], with the static camera)")
            ->check(finite());
    auto* f = cmd->add_option("--frame", args->frame,
                              "Frame number of the camera path (applies scripted edits up to it; "
                              "without a path: the animation at N/30 s)")
                  ->check(atLeast(0));
    t->excludes(f);
    auto* range = cmd->add_option("--frames", args->frames,
                                  "Render path frames FIRST..LAST (inclusive), every STEP-th, to "
                                  "numbered images (OUT_0000.png ...)")
                      ->type_name("FIRST:LAST[:STEP]")
                      ->check(frameRange());
    path->excludes(t)->excludes(f)->excludes(range);
    range->excludes(t)->excludes(f);
    cmd->add_option("--cache-mb", args->cacheMb,
                    "Far snapshot cache budget in MiB (default 256; LRU beyond)")
        ->check(numberIn(1, kMaxCacheMb, "MiB"));
    addCacheDirOptions(*cmd, args->cacheDir, "far snapshots are read from it before baking");
    cmd->add_option("--ids", args->ids,
                    "Also write the entity-id buffer as a colour-coded image (each entity its own "
                    "colour, black where none), and its key beside it: IDS_key.csv, the colour of "
                    "each entity shown");
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
    vox->add_option("--model", args->model,
                    "Which model of a multi-model file (default: a file with a scene graph "
                    "renders whole, else model 0)")
        ->check(atLeast(0));
    cmd->callback([args, modeOption] {
        args->modeGiven = modeOption->count() > 0;
        run(*args);
    });
}

} // namespace voxtier::cli
