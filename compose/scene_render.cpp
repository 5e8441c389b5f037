#include "compose/scene_render.hpp"

#include "core/camera.hpp"
#include "core/sprite.hpp"
#include "impostor_cache/far_blit.hpp"
#include "lod/frame_planner.hpp"

#include <algorithm>
#include <cmath>
#include <map>
#include <numbers>
#include <set>
#include <tuple>
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
    return frames_.finish(submit(frame, mode));
}

FrameResult SceneRenderer::renderAt(double time, RenderMode mode) {
    return frames_.finish(submitAt(time, mode));
}

FrameRenderer::PendingFrame SceneRenderer::submit(int frame, RenderMode mode,
                                                  const std::function<void()>& selected) {
    frames_.applyEditsThrough(frame);
    return frames_.submit(scene_.timeOfFrame(frame), mode, frame, selected);
}

FrameRenderer::PendingFrame SceneRenderer::submitAt(double time, RenderMode mode,
                                                    const std::function<void()>& selected) {
    const int frame = frameAtTime(scene_, time);
    frames_.applyEditsThrough(frame);
    return frames_.submit(time, mode, frame, selected);
}

FrameResult renderStill(const Scene& scene, const FrameOptions& options) {
    SceneRenderer renderer(scene, SceneCamera::Still, options);
    return renderer.render(0, RenderMode::Hybrid);
}

std::size_t SnapshotNeeds::snapshots() const {
    std::size_t n = 0;
    for (const SnapshotNeed& need : needs) n += need.views.size();
    return n;
}

namespace {

/// Which voxels a snapshot is of: scripted edits change a model frame at the path frames they
/// are due, and each change is a new set of snapshots.
class EditEpochs {
  public:
    explicit EditEpochs(const std::vector<ScriptedEdit>& edits) {
        for (const ScriptedEdit& e : edits) {
            std::vector<int>& at = due_[{e.model, e.modelFrame}];
            at.insert(std::upper_bound(at.begin(), at.end(), e.atFrame), e.atFrame);
            at.erase(std::unique(at.begin(), at.end()), at.end());
        }
    }
    /// The path frame whose edits model frame (model, frame) carries at path frame `pathFrame`
    /// (-1: none yet).
    int editedAt(int model, int frame, int pathFrame) const {
        const auto it = due_.find({model, frame});
        if (it == due_.end()) return -1;
        const auto past = std::upper_bound(it->second.begin(), it->second.end(), pathFrame);
        return past == it->second.begin() ? -1 : *(past - 1);
    }

  private:
    std::map<std::pair<int, int>, std::vector<int>> due_;
};

struct ViewLess {
    bool operator()(ViewId a, ViewId b) const {
        return std::tie(a.lattice.x, a.lattice.y, a.lattice.z) <
               std::tie(b.lattice.x, b.lattice.y, b.lattice.z);
    }
};

/// The snapshots asked for so far, by (editedAt, model, frame, sigma): the bake order.
class NeedSet {
  public:
    using Key = std::tuple<int, int, int, double>;
    static Key keyOf(const SpriteSetup& s, int editedAt) {
        return {editedAt, s.model, s.frame, s.lattice.sigma};
    }
    bool has(const Key& key, ViewId v) const {
        const auto it = views_.find(key);
        return it != views_.end() && it->second.count(v) > 0;
    }
    void add(const Key& key, ViewId v) { views_[key].insert(v); }
    SnapshotNeeds needs() const {
        SnapshotNeeds out;
        for (const auto& [key, views] : views_)
            out.needs.push_back({std::get<1>(key), std::get<2>(key), std::get<0>(key),
                                 std::get<3>(key),
                                 std::vector<ViewId>(views.begin(), views.end())});
        return out;
    }

  private:
    std::map<Key, std::set<ViewId, ViewLess>> views_;
};

/// `sprite` seen from `offsetDeg` degrees off its own direction, turned `turn` of a full circle
/// around it: what the planner reads of a sprite (its ray direction) for a camera that far off.
SpriteSetup seenFrom(const SpriteSetup& sprite, double offsetDeg, double turn) {
    const glm::dvec3 d = glm::normalize(sprite.lattice.dir);
    const glm::dvec3 a = glm::normalize(
        glm::cross(d, std::abs(d.x) < 0.9 ? glm::dvec3(1, 0, 0) : glm::dvec3(0, 1, 0)));
    const glm::dvec3 b = glm::cross(d, a);
    const double off = glm::radians(offsetDeg), around = 2.0 * std::numbers::pi * turn;
    SpriteSetup moved = sprite;
    moved.lattice.dir =
        std::cos(off) * d + std::sin(off) * (std::cos(around) * a + std::sin(around) * b);
    return moved;
}

/// Follows one render of a scene (the still, or the path's frames in order) through the planner
/// as it plans against a directory holding every snapshot, collecting what its far sprites are
/// drawn from into `needs` (shared by the renders followed).
class RenderFollower {
  public:
    RenderFollower(const Scene& scene, const SnapshotNeedOptions& options, const EditEpochs& epochs,
                   NeedSet& needs)
        : scene_(scene), options_(options), epochs_(epochs), needs_(needs),
          planner_(scene.selector) {}

    /// Path frame `frame` at time `time`, after the frames followed before it.
    void follow(int frame, double time) {
        const CameraFrame camera = makeCameraFrame(scene_.cameraAt(time));
        const std::vector<SpriteSetup> sprites = setupSprites(scene_, camera, time);
        // What this render holds in memory: what it drew on earlier frames (preferred by the
        // planner); every other snapshot is in the directory, so nothing is a bake.
        const PlanSettings settings = settingsFor([&](const SpriteSetup& s, ViewId v) {
            return memory_.has(NeedSet::keyOf(s, editedAt(s, frame)), v);
        });
        PlanStats stats;
        std::vector<std::pair<std::size_t, ViewId>> drawn;
        collect(sprites, planner_.plan(sprites, scene_.selector, settings, stats), drawn);
        const std::size_t drawnHere = drawn.size();
        if (options_.marginDeg) {
            // A fresh selector with nothing in memory: a lone render of this frame; with a
            // margin also one for each of 8 directions the margin off each entity's own.
            const auto nothing = [](const SpriteSetup&, ViewId) { return false; };
            const int samples = *options_.marginDeg > 0.0 ? 8 : 0;
            std::vector<SpriteSetup> moved = sprites;
            for (int k = -1; k < samples; ++k) {
                if (k >= 0)
                    for (std::size_t i = 0; i < sprites.size(); ++i)
                        if (sprites[i].visible())
                            moved[i] =
                                seenFrom(sprites[i], *options_.marginDeg, k / double(samples));
                FramePlanner fresh(scene_.selector);
                PlanStats st;
                collect(moved, fresh.plan(moved, scene_.selector, settingsFor(nothing), st), drawn);
            }
        }
        // The model frame, its edits and sigma are the entity's own whichever way it is seen.
        // The render holds what it drew from the next frame on, never what the margin adds.
        for (std::size_t k = 0; k < drawn.size(); ++k) {
            const auto& [i, view] = drawn[k];
            const NeedSet::Key key = NeedSet::keyOf(sprites[i], editedAt(sprites[i], frame));
            needs_.add(key, view);
            if (k < drawnHere) memory_.add(key, view);
        }
    }

  private:
    int editedAt(const SpriteSetup& s, int frame) const {
        return epochs_.editedAt(s.model, s.frame, frame);
    }
    PlanSettings settingsFor(ErrorBudgetViews::IsCached inMemory) const {
        PlanSettings settings;
        settings.mode = options_.mode == RenderMode::Far ? PlanMode::AllFar : PlanMode::Hybrid;
        settings.costAwareBakes = false; // nothing is baked: the cost bound has nothing to bound
        settings.inMemory = std::move(inMemory);
        settings.withoutBake = [](const SpriteSetup&, ViewId) { return true; };
        return settings;
    }
    /// The snapshots the far tier draws `plan` from (TierShares in compose/frame.cpp).
    void collect(const std::vector<SpriteSetup>& sprites, std::span<const EntityPlan> plan,
                 std::vector<std::pair<std::size_t, ViewId>>& drawn) const {
        const ViewSet set = viewSetFromSize(scene_.selector.viewSetSize);
        for (std::size_t i = 0; i < sprites.size(); ++i) {
            const EntityPlan& p = plan[i];
            if (!sprites[i].visible()) continue;
            if (p.drawsFar())
                drawn.emplace_back(i, p.view ? *p.view // not value_or: it searches every time
                                             : viewIdOf(set, chooseFarView(sprites[i], set)));
            if (p.fadeFromView && p.fade > 0.0f) drawn.emplace_back(i, *p.fadeFromView);
        }
    }

    const Scene& scene_;
    const SnapshotNeedOptions& options_;
    const EditEpochs& epochs_;
    NeedSet& needs_;
    NeedSet memory_; ///< what this render drew so far (its snapshot cache)
    FramePlanner planner_;
};

/// Frames of the longest animation loop of a scene's entities at 30 frames a second.
int animationLoopFrames(const Scene& scene) {
    double seconds = 0.0;
    for (const Entity& e : scene.entities)
        if (e.fps > 0.0 && e.model >= 0 && e.model < int(scene.models.size()))
            seconds = std::max(seconds, scene.models[std::size_t(e.model)]->frameCount() / e.fps);
    return seconds > 0.0 ? std::min(kMaxPathlessFrames, int(std::ceil(seconds * 30.0 - 1e-9))) : 0;
}

} // namespace

SnapshotNeeds snapshotsRendersAskFor(const Scene& scene, const SnapshotNeedOptions& options) {
    NeedSet needs;
    if (options.mode != RenderMode::Hybrid && options.mode != RenderMode::Far) return {};
    const EditEpochs epochs(scene.edits);
    // The still, where it is not the path's first frame: a render of its own, fresh.
    Scene still = scene;
    applyCameraRule(still, SceneCamera::Still);
    const bool stillOfItsOwn = !still.path;
    if (stillOfItsOwn)
        RenderFollower(still, options, epochs, needs).follow(0, still.timeOfFrame(0));
    // The path's frames in order (a --path render), or without a path the static camera over
    // the animation (a --frames render of a scene without one).
    const int frames = scene.path ? scene.path->frameCount() : animationLoopFrames(scene);
    RenderFollower path(scene, options, epochs, needs);
    for (int f = 0; f < frames; ++f) path.follow(f, scene.timeOfFrame(f));
    SnapshotNeeds out = needs.needs();
    out.still = stillOfItsOwn;
    out.frames = frames;
    return out;
}

} // namespace voxtier
