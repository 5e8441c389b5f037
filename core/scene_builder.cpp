// loadSceneJson (core/scene_loader.hpp): a parsed scene document, section by section, into a
// Scene. Every key a section accepts is listed in core/scene_keys.cpp, by the section's name in
// docs/scene.schema.json.
#include "core/detail/json_fields.hpp"
#include "core/error.hpp"
#include "core/procedural.hpp"
#include "core/scene_keys.hpp"
#include "core/scene_loader.hpp"
#include "core/splitmix64.hpp"
#include "core/sprite.hpp"

#include <glm/gtc/quaternion.hpp>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <map>
#include <optional>
#include <string_view>
#include <unordered_map>

namespace voxtier {

namespace fs = std::filesystem;

namespace {

using namespace detail;

/// The union of the keys of several kinds of object, for an object whose kind is not known yet
/// (a misspelt key is then reported as such, not as a missing kind).
std::vector<std::string_view> keysOfAny(std::initializer_list<std::string_view> objects) {
    std::vector<std::string_view> keys;
    for (std::string_view o : objects)
        for (std::string_view k : sceneKeysOf(o))
            if (std::find(keys.begin(), keys.end(), k) == keys.end()) keys.push_back(k);
    return keys;
}

struct VoxCacheEntry {
    VoxFile file;
    /// (file model, mirror axis) -> Scene::models index, shared by every vox_scenes entry of
    /// this file, so the far tier bakes each distinct model once.
    std::map<std::pair<int, int>, int> sceneModels;
};

struct SceneBuilder {
    Ctx c;
    Scene s;
    std::unordered_map<std::string, int> modelByName; ///< declared models only
    std::vector<std::string> modelNames;
    std::size_t voxelCells = 0; ///< over all models and frames so far (Limits::kMaxSceneVoxelCells)
    std::map<std::string, VoxCacheEntry> voxCache; ///< by resolved path

    // Paths -------------------------------------------------------------------------------
    fs::path resolve(const json& v, const std::string& path) {
        const std::string rel = nonEmptyString(c, v, path);
        fs::path p(rel);
        if (p.is_relative()) p = c.baseDir / p;
        std::error_code ec;
        const auto st = fs::status(p, ec);
        if (!fs::exists(st)) {
            // A scene file named without a folder has the empty one: name the current folder.
            std::error_code cwdError;
            const std::string folder =
                c.baseDir.empty()
                    ? "the current folder '" + fs::current_path(cwdError).string() + "'"
                    : "'" + c.baseDir.string() + "'";
            fail(c, path,
                 "file not found: '" + p.string() + "'" +
                     (fs::path(rel).is_relative()
                          ? " ('" + rel + "' is resolved against the scene file's folder, " +
                                folder + ")"
                          : ""));
        }
        if (fs::is_directory(st)) fail(c, path, "'" + p.string() + "' is a directory, not a file");
        return p;
    }

    VoxCacheEntry& vox(const json& v, const std::string& path) {
        const fs::path p = resolve(v, path);
        std::error_code ec;
        fs::path key = fs::weakly_canonical(p, ec);
        if (ec) key = p;
        auto it = voxCache.find(key.string());
        if (it != voxCache.end()) return it->second;
        VoxCacheEntry e;
        try {
            e.file = readVoxFile(p);
        } catch (const InputError& err) {
            // The reader's message names the .vox file and chunk; keep it whole.
            fail(c, path, err.what());
        } catch (const std::exception& err) {
            fail(c, path, "cannot read '" + p.string() + "': " + err.what());
        }
        return voxCache.emplace(key.string(), std::move(e)).first->second;
    }

    int modelIndex(const json& v, const std::string& path) {
        const std::string name = string(c, v, path);
        const auto it = modelByName.find(name);
        if (it == modelByName.end())
            fail(c, path, "unknown model '" + name + "'" + suggestion(name, modelNames));
        return it->second;
    }

    void checkEntityBudget(std::size_t adding, const std::string& path) {
        const std::size_t total = s.entities.size() + adding;
        if (total > std::size_t(Limits::kMaxEntities))
            fail(c, path,
                 "scene would have " + std::to_string(total) + " entities; the limit is " +
                     std::to_string(Limits::kMaxEntities));
    }

    /// Counts `cells` more voxel cells against Limits::kMaxSceneVoxelCells, before they exist.
    void reserveVoxelCells(std::size_t cells, const std::string& path) {
        if (cells > Limits::kMaxSceneVoxelCells - std::min(voxelCells, Limits::kMaxSceneVoxelCells))
            fail(c, path,
                 "the scene's models would need " + std::to_string(voxelCells + cells) +
                     " voxel cells; the limit is " + std::to_string(Limits::kMaxSceneVoxelCells));
        voxelCells += cells;
    }

    // Sections ----------------------------------------------------------------------------
    void render(const Obj& root) {
        root.pos("voxel_size", s.render.voxelSize);
        root.pos("sigma", s.render.sigma);
        if (s.render.sigma > Limits::kMaxSigma)
            fail(c, root.at("sigma"),
                 "expected at most " + std::to_string(int(Limits::kMaxSigma)) +
                     " virtual pixels per voxel (snapshot memory grows with its square)");
        if (auto v = root.get("view_mode"))
            s.render.viewMode = choice(c, *v, root.at("view_mode"), {"per_entity", "parallel"}) == 0
                                    ? ViewMode::PerEntity
                                    : ViewMode::Parallel;
        if (auto v = root.get("background")) {
            // [r, g, b] or [r, g, b, a]: alpha 0 makes the background transparent in PNG/EXR.
            const std::string p = root.at("background");
            if (v->is_array() && v->size() == 4)
                s.render.background =
                    (color(c, json::array({(*v)[0], (*v)[1], (*v)[2]}), p) & 0x00FFFFFFu) |
                    (Rgba8(intIn(c, (*v)[3], element(p, 3), 0, 255)) << 24);
            else
                s.render.background = color(c, *v, p);
        }
    }

    /// makeCameraFrame's checks, reported at `path` (it throws with file "" and a field that
    /// starts with "camera").
    void checkCamera(const Camera& cam, const std::string& path) {
        if (!std::isfinite(glm::length(cam.target - cam.position)))
            fail(c, path + ".target", "position and target are too far apart to subtract");
        try {
            makeCameraFrame(cam);
        } catch (const InputError& e) {
            std::string field = e.field();
            if (field.rfind("camera", 0) == 0) field = path + field.substr(6);
            fail(c, field, e.reason());
        }
    }

    void fovField(const Obj& o, std::string_view key, double& out) {
        if (auto v = o.get(key)) {
            const double f = number(c, *v, o.at(key));
            if (!(f > 0.0 && f < 179.0))
                fail(c, o.at(key), "expected a field of view in (0, 179) degrees, got " + fmt(f));
            out = f;
        }
    }

    void camera(const Obj& root) {
        const json* v = root.get("camera");
        if (!v) return;
        const Obj o(c, *v, root.at("camera"));
        o.allow(sceneKeysOf("camera"));
        Camera& cam = s.camera;
        o.v3("position", cam.position);
        s.cameraPositioned = o.get("position") != nullptr;
        o.v3("target", cam.target);
        o.v3("up", cam.up);
        fovField(o, "fov_y", cam.fovYDeg);
        if (auto sz = o.get("size")) {
            const std::string p = o.at("size");
            arrayOf(c, *sz, p, 2, "integers (width, height)");
            cam.width = intIn(c, (*sz)[0], element(p, 0), 1, Limits::kMaxImageDim);
            cam.height = intIn(c, (*sz)[1], element(p, 1), 1, Limits::kMaxImageDim);
        }
        o.pos("near", cam.zNear);
        checkCamera(cam, o.path());
    }

    void cameraPath(const Obj& root) {
        const json* v = root.get("camera_path");
        if (!v) return;
        const Obj o(c, *v, root.at("camera_path"));
        o.allow(sceneKeysOf("camera_path"));
        CameraPath path;
        o.pos("fps", path.fps);
        const std::string keysPath = o.at("keys");
        const json& keys = array(c, o.require("keys"), keysPath);
        if (keys.empty()) fail(c, keysPath, "expected at least one key");
        for (std::size_t i = 0; i < keys.size(); ++i) {
            const Obj k(c, keys[i], element(keysPath, i));
            k.allow(sceneKeysOf("camera_key"));
            CameraKey key;
            key.time = number(c, k.require("time"), k.at("time"));
            key.position = vec3(c, k.require("position"), k.at("position"));
            key.target = vec3(c, k.require("target"), k.at("target"));
            if (auto u = k.get("up")) key.up = vec3(c, *u, k.at("up"));
            if (k.get("fov_y")) {
                double f = 0.0;
                fovField(k, "fov_y", f);
                key.fovYDeg = f;
            }
            if (i > 0 && !(key.time > path.keys.back().time))
                fail(c, k.at("time"),
                     "key times must be strictly increasing: " + fmt(key.time) +
                         " does not follow " + fmt(path.keys.back().time));
            Camera cam = s.camera;
            cam.position = key.position;
            cam.target = key.target;
            if (key.up) cam.up = *key.up;
            if (key.fovYDeg) cam.fovYDeg = *key.fovYDeg;
            checkCamera(cam, k.path());
            path.keys.push_back(key);
        }
        // Interpolation can pass through a degenerate camera (position crossing the target, up
        // swinging through the view direction) even when every key is fine, and the renderer
        // asks for exactly the frame times, so check those.
        constexpr double kMaxFrames = 1'000'000;
        const double frames = path.duration() * path.fps;
        if (!(frames < kMaxFrames))
            fail(c, o.path(), "the path is " + fmt(frames) + " frames long; the limit is 1000000");
        s.path = path;
        const int n = s.path->frameCount();
        for (int f = 0; f < n; ++f) {
            const double t = s.timeOfFrame(f);
            try {
                makeCameraFrame(s.cameraAt(t));
            } catch (const InputError& e) {
                fail(c, o.path(),
                     "the interpolated camera at frame " + std::to_string(f) + " (t = " + fmt(t) +
                         " s) is degenerate: " + e.reason());
            }
        }
    }

    void light(const Obj& root) {
        const json* v = root.get("light");
        if (!v) return;
        const Obj o(c, *v, root.at("light"));
        o.allow(sceneKeysOf("light"));
        o.v3("direction", s.light.direction);
        const double len = glm::length(s.light.direction);
        if (!(len > 0.0 && std::isfinite(len)))
            fail(c, o.at("direction"), "expected a non-zero direction");
        o.nonNeg("ambient", s.light.ambient);
        o.nonNeg("diffuse", s.light.diffuse);
    }

    void ground(const Obj& root) {
        const json* v = root.get("ground");
        if (!v) return;
        const Obj o(c, *v, root.at("ground"));
        o.allow(sceneKeysOf("ground"));
        GroundPlane& g = s.ground.emplace();
        o.num("height", g.height);
        o.pos("spacing", g.spacing);
        o.nonNeg("line_width", g.lineWidth);
        o.pos("fade_distance", g.fadeDistance);
        if (auto col = o.get("color")) g.color = color(c, *col, o.at("color"));
        if (auto col = o.get("line_color")) g.lineColor = color(c, *col, o.at("line_color"));
    }

    void selector(const Obj& root) {
        const json* v = root.get("selector");
        if (!v) return;
        const Obj o(c, *v, root.at("selector"));
        o.allow(sceneKeysOf("selector"));
        SelectorConfig& sel = s.selector;
        if (auto m = o.get("metric"))
            sel.metric = SelectorMetric(
                choice(c, *m, o.at("metric"),
                       {toString(SelectorMetric::Distance), toString(SelectorMetric::RadiusPx),
                        toString(SelectorMetric::ErrorPx), toString(SelectorMetric::ErrorBudget)}));
        // Distance grows with distance; the pixel metrics (projected radius, predicted
        // view-quantisation error) shrink with it, so their hysteresis band is mirrored:
        // near->far below far_at, far->near above near_at > far_at (lod/selector.hpp).
        const bool pixelMetric = sel.metric != SelectorMetric::Distance;
        if (pixelMetric) {
            const SelectorConfig d = defaultSelectorFor(sel.metric);
            sel.nearAt = d.nearAt;
            sel.farAt = d.farAt;
        }
        o.nonNeg("near_at", sel.nearAt);
        o.nonNeg("far_at", sel.farAt);
        if (!pixelMetric && !(sel.farAt > sel.nearAt))
            fail(c, o.at(o.get("far_at") ? "far_at" : "near_at"),
                 "far_at must be greater than near_at (got near_at " + fmt(sel.nearAt) +
                     ", far_at " + fmt(sel.farAt) + ")");
        if (pixelMetric && !(sel.nearAt > sel.farAt))
            fail(c, o.at(o.get("far_at") ? "far_at" : "near_at"),
                 "for a pixel metric near_at must be greater than far_at (entities go far when "
                 "they shrink below far_at; got near_at " +
                     fmt(sel.nearAt) + ", far_at " + fmt(sel.farAt) + ")");
        o.nonNeg("view_hysteresis_deg", sel.viewHysteresisDeg);
        if (!(sel.viewHysteresisDeg < 180.0))
            fail(c, o.at("view_hysteresis_deg"), "expected an angle in [0, 180) degrees");
        o.i("crossfade_frames", sel.crossfadeFrames, 0, 1'000'000);
        if (auto vs = o.get("view_set")) {
            const int n = intIn(c, *vs, o.at("view_set"), 0, 1000);
            if (n != 26 && n != 98 && n != 218)
                fail(c, o.at("view_set"), "expected 26, 98 or 218, got " + std::to_string(n));
            sel.viewSetSize = n;
        }
        o.pos("budget_vpx", sel.budgetVpx);
        if (auto cap = o.get("ladder_cap")) {
            const int n = intIn(c, *cap, o.at("ladder_cap"), 1, 64);
            if ((n & (n - 1)) != 0)
                fail(c, o.at("ladder_cap"),
                     "expected 1, 2, 4, 8, 16, 32 or 64, got " + std::to_string(n));
            sel.ladderCap = n;
        }
        o.i("max_bakes_per_frame", sel.maxBakesPerFrame, 0, 1'000'000);
        o.i("snapshot_scale", sel.snapshotScale, 1, kMaxSnapshotScale);
    }

    std::string modelName(const Obj& o) {
        const std::string name = nonEmptyString(c, o.require("name"), o.at("name"));
        if (modelByName.count(name)) fail(c, o.at("name"), "duplicate model name '" + name + "'");
        return name;
    }

    /// Index of a model in a .vox file with `count` models (the message says how many there are).
    int fileModelIndex(const json& v, const std::string& path, int count) {
        const long long m = integer(c, v, path, 0, std::numeric_limits<int>::max());
        if (m >= count)
            fail(c, path,
                 "model index " + std::to_string(m) + " out of range: the file has " +
                     std::to_string(count) + " model(s)");
        return int(m);
    }

    std::shared_ptr<VoxelModel> voxModel(const Obj& o) {
        o.allow(sceneKeysOf("vox_model"));
        const std::string name = modelName(o);
        if (o.get("model") && o.get("frames"))
            fail(c, o.at("frames"), "give either 'model' or 'frames', not both");
        const VoxFile& f = vox(o.require("vox"), o.at("vox")).file;
        const int count = int(f.models.size());
        if (count == 0) fail(c, o.at("vox"), "the file has no models");
        std::vector<int> which;
        if (const json* fr = o.get("frames")) {
            const std::string p = o.at("frames");
            if (fr->is_string()) {
                if (fr->get<std::string>() != "all")
                    fail(c, p, "expected \"all\" or an array of model indices");
                for (int i = 0; i < count; ++i) which.push_back(i);
            } else if (fr->is_array() && !fr->empty()) {
                for (std::size_t i = 0; i < fr->size(); ++i)
                    which.push_back(fileModelIndex((*fr)[i], element(p, i), count));
            } else {
                fail(c, p, "expected \"all\" or a non-empty array of model indices");
            }
            if (which.size() > std::size_t(Limits::kMaxFramesPerModel))
                fail(c, p,
                     std::to_string(which.size()) + " frames; the limit is " +
                         std::to_string(Limits::kMaxFramesPerModel));
        } else {
            const json* mv = o.get("model");
            which.push_back(mv ? fileModelIndex(*mv, o.at("model"), count) : 0);
        }
        std::size_t cells = 0;
        for (int m : which) {
            const glm::ivec3 d = f.models[std::size_t(m)].dims();
            cells += std::size_t(d.x) * std::size_t(d.y) * std::size_t(d.z);
        }
        reserveVoxelCells(cells, o.path());
        std::vector<VoxelGrid> frames;
        frames.reserve(which.size());
        for (int m : which) frames.push_back(f.models[std::size_t(m)]);
        return std::make_shared<VoxelModel>(name, f.palette, std::move(frames));
    }

    /// {"generator": "tank", "seed", "frames", "size"}: an animated model, kept whole.
    std::shared_ptr<VoxelModel> tankModel(const Obj& o) {
        o.allow(sceneKeysOf("tank_model"));
        const std::string name = modelName(o);
        std::uint64_t seed = 1;
        if (auto v = o.get("seed")) seed = seedValue(c, *v, o.at("seed"));
        int frames = 8;
        o.i("frames", frames, 1, Limits::kMaxFramesPerModel);
        glm::ivec3 size(32, 32, 16);
        if (auto v = o.get("size")) size = ivec3(c, *v, o.at("size"), 8, Limits::kMaxModelDim);
        reserveVoxelCells(std::size_t(size.x) * std::size_t(size.y) * std::size_t(size.z) *
                              std::size_t(frames),
                          o.path());
        auto m = makeTank(seed, frames, size);
        m->setName(name);
        return m;
    }

    std::shared_ptr<VoxelModel> generatorModel(const Obj& o) {
        static const std::vector<std::string> kinds{"box",   "sphere", "arrow",
                                                    "shell", "voxel",  "tank"};
        const int kind = choice(c, o.require("generator"), o.at("generator"), kinds);
        if (kind == 5) return tankModel(o);
        switch (kind) {
        case 0:
            o.allow(sceneKeysOf("box_model"));
            break;
        case 1:
            o.allow(sceneKeysOf("sphere_model"));
            break;
        case 2:
            o.allow(sceneKeysOf("arrow_model"));
            break;
        case 3:
            o.allow(sceneKeysOf("shell_model"));
            break;
        default:
            o.allow(sceneKeysOf("voxel_model"));
            break;
        }
        const std::string name = modelName(o);
        int index = 1;
        o.i("index", index, 1, 255);
        const auto idx = std::uint8_t(index);
        glm::ivec3 size = kind == 3 ? glm::ivec3(16) : glm::ivec3(8);
        if (auto v = o.get("size")) size = ivec3(c, *v, o.at("size"), 1, Limits::kMaxModelDim);
        std::shared_ptr<VoxelModel> m;
        switch (kind) {
        case 0:
            m = makeBox(size, idx);
            break;
        case 1: {
            int r = 6;
            o.i("radius", r, 1, Limits::kMaxModelDim / 2);
            m = makeSphere(r, idx);
            break;
        }
        case 2: {
            int len = 16;
            o.i("length", len, 8, Limits::kMaxModelDim);
            m = makeArrow(len);
            break;
        }
        case 3: {
            int t = 1;
            o.i("thickness", t, 1, Limits::kMaxModelDim);
            m = makeShell(size, t, idx);
            break;
        }
        default:
            m = makeSingleVoxel(idx);
            break;
        }
        // One frame of at most 256³ exists before it is counted; a tank's frames are counted first.
        const glm::ivec3 d = m->frame(0).dims();
        reserveVoxelCells(std::size_t(d.x) * std::size_t(d.y) * std::size_t(d.z), o.path());
        Palette pal = m->palette();
        if (auto v = o.get("color")) pal.colors[idx] = color(c, *v, o.at("color"));
        return std::make_shared<VoxelModel>(name, pal, std::vector<VoxelGrid>{m->frame(0)});
    }

    void models(const Obj& root) {
        const std::string path = root.at("models");
        const json& list = array(c, root.require("models"), path);
        if (list.empty()) fail(c, path, "expected at least one model");
        for (std::size_t i = 0; i < list.size(); ++i) {
            const Obj o(c, list[i], element(path, i));
            const bool isVox = o.get("vox") != nullptr, isGen = o.get("generator") != nullptr;
            if (isVox && isGen) fail(c, o.path(), "give either 'vox' or 'generator', not both");
            if (!isVox && !isGen) {
                // Report a misspelt key as such before complaining that the source is missing.
                o.allow(keysOfAny({"vox_model", "box_model", "sphere_model", "arrow_model",
                                   "shell_model", "voxel_model", "tank_model"}));
                fail(c, o.path(), "missing 'vox' (a .vox file) or 'generator'");
            }
            auto m = isVox ? voxModel(o) : generatorModel(o);
            modelByName.emplace(m->name(), int(s.models.size()));
            modelNames.push_back(m->name());
            s.models.push_back(std::move(m));
        }
    }

    void entities(const Obj& root) {
        const json* v = root.get("entities");
        if (!v) return;
        const std::string path = root.at("entities");
        const json& list = array(c, *v, path);
        checkEntityBudget(list.size(), path);
        for (std::size_t i = 0; i < list.size(); ++i) {
            const Obj o(c, list[i], element(path, i));
            o.allow(sceneKeysOf("entity"));
            Entity e;
            e.model = modelIndex(o.require("model"), o.at("model"));
            const VoxelModel& m = *s.models[std::size_t(e.model)];
            o.v3("position", e.position);
            if (o.get("rotation_deg") && o.get("quaternion"))
                fail(c, o.at("quaternion"), "give either rotation_deg or quaternion, not both");
            if (auto r = o.get("rotation_deg"))
                e.rotation = quatFromEulerDeg(vec3(c, *r, o.at("rotation_deg")));
            if (auto q = o.get("quaternion")) {
                const std::string p = o.at("quaternion");
                arrayOf(c, *q, p, 4, "finite numbers [w, x, y, z]");
                double w[4];
                for (int k = 0; k < 4; ++k) {
                    const json& x = (*q)[std::size_t(k)];
                    if (!x.is_number() || !std::isfinite(x.get<double>()))
                        fail(c, p, "expected an array of 4 finite numbers [w, x, y, z]");
                    w[k] = x.get<double>();
                }
                const glm::dquat raw(w[0], w[1], w[2], w[3]);
                const double len = glm::length(raw);
                if (!(len >= 1e-12) || !std::isfinite(len))
                    fail(c, p,
                         "expected a non-zero quaternion [w, x, y, z] (norm " + fmt(len) + ")");
                e.rotation = raw / len;
            }
            o.pos("scale", e.scale);
            if (auto a = o.get("anchor")) e.anchor = vec3(c, *a, o.at("anchor"));
            o.i("frame", e.frame, 0, std::max(0, m.frameCount() - 1));
            o.nonNeg("fps", e.fps);
            o.str("name", e.name);
            s.entities.push_back(std::move(e));
        }
    }

    /// What every entity of one crowd shares, and the crowd's splitmix64 stream.
    struct Crowd {
        std::vector<int> pool; ///< model indices
        int count = 0;
        bool randomYaw = false, randomFrame = false;
        double scale = 1.0, fps = 0.0;
        std::string prefix; ///< entity k is named prefix#k
        SplitMix64 rng{1};
    };

    void crowds(const Obj& root) {
        const json* v = root.get("crowds");
        if (!v) return;
        const std::string path = root.at("crowds");
        const json& list = array(c, *v, path);
        for (std::size_t i = 0; i < list.size(); ++i) {
            const Obj o(c, list[i], element(path, i));
            const bool random = o.get("layout") && choice(c, *o.get("layout"), o.at("layout"),
                                                          {"grid", "random"}) == 1;
            if (random)
                o.allow(sceneKeysOf("random_crowd"));
            else
                o.allow(sceneKeysOf("grid_crowd"));
            Crowd crowd = crowdSettings(o, element(path, i));
            s.entities.reserve(s.entities.size() + std::size_t(crowd.count));
            if (random)
                randomCrowd(o, crowd);
            else
                gridCrowd(o, crowd);
        }
    }

    /// The keys both layouts share, checked in this order whatever the order in the file.
    Crowd crowdSettings(const Obj& o, const std::string& defaultPrefix) {
        Crowd crowd;
        const std::string mp = o.at("models");
        const json& ml = array(c, o.require("models"), mp);
        if (ml.empty()) fail(c, mp, "expected at least one model name");
        for (std::size_t k = 0; k < ml.size(); ++k)
            crowd.pool.push_back(modelIndex(ml[k], element(mp, k)));

        crowd.count = intIn(c, o.require("count"), o.at("count"), 0, Limits::kMaxEntities);
        checkEntityBudget(std::size_t(crowd.count), o.at("count"));
        std::uint64_t seed = 1;
        if (auto sv = o.get("seed")) seed = seedValue(c, *sv, o.at("seed"));
        crowd.rng = SplitMix64{seed};
        o.flag("random_yaw", crowd.randomYaw);
        o.pos("scale", crowd.scale);
        o.nonNeg("fps", crowd.fps);
        o.flag("random_frame", crowd.randomFrame);
        crowd.prefix = defaultPrefix;
        o.str("name", crowd.prefix);
        return crowd;
    }

    /// Entity k of the crowd at `p`; draws its yaw, then its start frame, when those are random.
    void addCrowdEntity(Crowd& crowd, int model, glm::dvec3 p, int k) {
        Entity e;
        e.model = model;
        e.position = p;
        e.scale = crowd.scale;
        if (crowd.randomYaw) e.rotation = quatFromEulerDeg({0.0, crowd.rng.unit() * 360.0, 0.0});
        const int frames = s.models[std::size_t(model)]->frameCount();
        if (crowd.randomFrame) e.frame = int(crowd.rng.below(std::uint64_t(frames)));
        e.fps = crowd.fps;
        e.name = crowd.prefix + "#" + std::to_string(k);
        s.entities.push_back(std::move(e));
    }

    void randomCrowd(const Obj& o, Crowd& crowd) {
        const Obj area(c, o.require("area"), o.at("area"));
        area.allow(sceneKeysOf("crowd_area"));
        const glm::dvec2 lo = vec2(c, area.require("min"), area.at("min"));
        const glm::dvec2 hi = vec2(c, area.require("max"), area.at("max"));
        if (!(lo.x <= hi.x && lo.y <= hi.y))
            fail(c, area.at("max"), "expected max >= min on both axes");
        if (!std::isfinite(hi.x - lo.x) || !std::isfinite(hi.y - lo.y))
            fail(c, area.path(), "the area is too large");
        double y = 0.0;
        o.num("y", y);
        for (int k = 0; k < crowd.count; ++k) {
            const int model = crowd.pool[std::size_t(crowd.rng.below(crowd.pool.size()))];
            const double x = lo.x + crowd.rng.unit() * (hi.x - lo.x);
            const double z = lo.y + crowd.rng.unit() * (hi.y - lo.y);
            addCrowdEntity(crowd, model, {x, y, z}, k);
        }
    }

    void gridCrowd(const Obj& o, Crowd& crowd) {
        glm::dvec3 origin(0.0);
        o.v3("origin", origin);
        glm::dvec2 spacing(2.0);
        if (auto sp = o.get("spacing")) spacing = vec2(c, *sp, o.at("spacing"));
        int columns = std::max(1, int(std::ceil(std::sqrt(double(crowd.count)))));
        o.i("columns", columns, 1, Limits::kMaxEntities);
        for (int k = 0; k < crowd.count; ++k) {
            const glm::dvec3 p =
                origin + glm::dvec3(spacing.x * (k % columns), 0.0, spacing.y * (k / columns));
            addCrowdEntity(crowd, crowd.pool[std::size_t(k) % crowd.pool.size()], p, k);
        }
    }

    void voxScenes(const Obj& root) {
        const json* v = root.get("vox_scenes");
        if (!v) return;
        const std::string path = root.at("vox_scenes");
        const json& list = array(c, *v, path);
        for (std::size_t i = 0; i < list.size(); ++i) {
            const Obj o(c, list[i], element(path, i));
            o.allow(sceneKeysOf("vox_scene"));
            VoxCacheEntry& entry = vox(o.require("vox"), o.at("vox"));
            glm::dvec3 position(0.0);
            o.v3("position", position);
            double scale = 1.0;
            o.pos("scale", scale);
            bool hidden = false;
            o.flag("include_hidden", hidden);
            FlattenedVoxScene flat;
            try {
                flat = flattenVoxScene(entry.file, position, scale, hidden, s.render.voxelSize);
            } catch (const InputError& e) {
                fail(c, o.at("vox"), e.what());
            }
            checkEntityBudget(flat.entities.size(), o.path());
            std::vector<int> remap(flat.models.size());
            for (std::size_t m = 0; m < flat.models.size(); ++m) {
                auto [it, inserted] =
                    entry.sceneModels.emplace(flat.modelKeys[m], int(s.models.size()));
                if (inserted) s.models.push_back(flat.models[m]);
                remap[m] = it->second;
            }
            for (Entity& e : flat.entities) {
                e.model = remap[std::size_t(e.model)];
                s.entities.push_back(std::move(e));
            }
        }
    }

    void edits(const Obj& root) {
        const json* v = root.get("edits");
        if (!v) return;
        const std::string path = root.at("edits");
        const json& list = array(c, *v, path);
        for (std::size_t i = 0; i < list.size(); ++i) {
            const Obj o(c, list[i], element(path, i));
            ScriptedEdit e;
            if (!o.get("op")) {
                o.allow(keysOfAny({"set_edit", "fill_edit", "clear_edit"}));
                o.require("op");
            }
            e.op =
                ScriptedEdit::Op(choice(c, o.require("op"), o.at("op"), {"set", "fill", "clear"}));
            switch (e.op) {
            case ScriptedEdit::Op::Set:
                o.allow(sceneKeysOf("set_edit"));
                break;
            case ScriptedEdit::Op::Fill:
                o.allow(sceneKeysOf("fill_edit"));
                break;
            case ScriptedEdit::Op::Clear:
                o.allow(sceneKeysOf("clear_edit"));
                break;
            }
            e.atFrame =
                intIn(c, o.require("frame"), o.at("frame"), 0, std::numeric_limits<int>::max());
            e.model = modelIndex(o.require("model"), o.at("model"));
            const VoxelModel& m = *s.models[std::size_t(e.model)];
            o.i("model_frame", e.modelFrame, 0, m.frameCount() - 1);
            const glm::ivec3 dims = m.frame(e.modelFrame).dims();
            const std::string dimsText = std::to_string(dims.x) + "x" + std::to_string(dims.y) +
                                         "x" + std::to_string(dims.z);
            if (e.op == ScriptedEdit::Op::Set) {
                const glm::ivec3 at =
                    ivec3(c, o.require("at"), o.at("at"), 0, Limits::kMaxModelDim);
                if (!Box3i{{0, 0, 0}, dims}.contains(at))
                    fail(c, o.at("at"), "voxel outside the " + dimsText + " model");
                e.box = {at, at + 1};
            } else {
                e.box.min = ivec3(c, o.require("min"), o.at("min"), 0, Limits::kMaxModelDim);
                e.box.max = ivec3(c, o.require("max"), o.at("max"), 0, Limits::kMaxModelDim);
                if (glm::any(glm::greaterThanEqual(e.box.min, e.box.max)))
                    fail(c, o.at("max"), "expected max > min on every axis (max is exclusive)");
                if (glm::any(glm::greaterThan(e.box.max, dims)))
                    fail(c, o.at("max"), "box outside the " + dimsText + " model");
            }
            int index = e.op == ScriptedEdit::Op::Clear ? 0 : 1;
            o.i("index", index, 0, 255);
            e.index = std::uint8_t(index);
            s.edits.push_back(e);
        }
        std::stable_sort(
            s.edits.begin(), s.edits.end(),
            [](const ScriptedEdit& a, const ScriptedEdit& b) { return a.atFrame < b.atFrame; });
    }

    Scene run(const json& j) {
        if (!j.is_object())
            fail(c, "", std::string("expected a JSON object at the top level, got ") + typeName(j));
        const Obj root(c, j, "");
        root.allow(sceneKeysOf("scene"));
        if (auto d = root.get("description")) string(c, *d, "description");
        // "$schema" only tells an editor where docs/scene.schema.json is.
        if (auto d = root.get("$schema")) string(c, *d, "$schema");
        s.source = c.file;
        render(root);
        camera(root);
        cameraPath(root);
        light(root);
        ground(root);
        selector(root);
        models(root);
        entities(root);
        crowds(root);
        voxScenes(root);
        edits(root);
        return std::move(s);
    }
};

} // namespace

glm::dquat quatFromEulerDeg(glm::dvec3 r) {
    const glm::dquat qy = glm::angleAxis(glm::radians(r.y), glm::dvec3(0, 1, 0));
    const glm::dquat qx = glm::angleAxis(glm::radians(r.x), glm::dvec3(1, 0, 0));
    const glm::dquat qz = glm::angleAxis(glm::radians(r.z), glm::dvec3(0, 0, 1));
    return glm::normalize(qy * qx * qz);
}

Scene loadSceneJson(const json& j, const std::string& sourceName, const fs::path& baseDir) {
    SceneBuilder l{Ctx{sourceName, baseDir}, {}, {}, {}, {}};
    return l.run(j);
}

} // namespace voxtier
