#include "core/sprite_store.hpp"

#include <tbb/blocked_range.h>
#include <tbb/parallel_reduce.h>

#include <algorithm>
#include <array>
#include <stdexcept>
#include <string>

namespace voxtier {

namespace {

bool sameCamera(const CameraFrame& a, const CameraFrame& b) {
    return a.eye == b.eye && a.forward == b.forward && a.right == b.right && a.up == b.up &&
           a.tanHalfFovY == b.tanHalfFovY && a.width == b.width && a.height == b.height &&
           a.zNear == b.zNear;
}

bool sameParams(const RenderParams& a, const RenderParams& b) {
    return a.voxelSize == b.voxelSize && a.sigma == b.sigma && a.viewMode == b.viewMode;
}

bool sameLight(const Light& a, const Light& b) {
    return a.direction == b.direction && a.ambient == b.ambient && a.diffuse == b.diffuse;
}

/// Two frames in flight (a path render) and the one being set up; a caller that keeps more
/// results gets fresh arrays for them.
constexpr std::size_t kSpriteArrays = 3;

} // namespace

SpriteHistory SpriteStore::history() const {
    if (arrays_.empty() || !valid_) return {};
    return {id_, updates_, sprites(), changedAt_, posedAt_, allChangedAt_, visible_, depths_};
}

std::span<const SpriteSetup> SpriteStore::sprites() const {
    if (arrays_.empty()) return {};
    return *arrays_[current_].array;
}

SharedVector<SpriteSetup> SpriteStore::shareSprites() const {
    if (arrays_.empty()) return {};
    return SharedVector<SpriteSetup>(arrays_[current_].array);
}

SpriteStore::Sprites& SpriteStore::writableSprites(std::size_t n) {
    Sprites* best = nullptr;
    for (Sprites& a : arrays_)
        if (a.array.use_count() == 1 && (!best || a.asOf > best->asOf)) best = &a;
    if (!best) {
        // Every array is held by some frame: a new one, in place of the oldest kept.
        if (arrays_.size() >= kSpriteArrays) {
            auto oldest = std::min_element(
                arrays_.begin(), arrays_.end(),
                [](const Sprites& a, const Sprites& b) { return a.asOf < b.asOf; });
            arrays_.erase(oldest);
        }
        arrays_.push_back({std::make_shared<std::vector<SpriteSetup>>(), 0});
        best = &arrays_.back();
    }
    if (best->array->size() != n) best->array->resize(n), best->asOf = 0;
    current_ = std::size_t(best - arrays_.data());
    return *best;
}

void SpriteStore::clear() {
    keys_.clear();
    constants_.clear();
    arrays_.clear();
    current_ = 0;
    changedAt_.clear();
    posedAt_.clear();
    allChangedAt_ = 0;
    changed_.clear();
    reposed_.clear();
    visible_.clear();
    depths_.clear();
    selection_.clear();
    selectionCurrent_ = false;
    visibleIds_.writable().clear();
    valid_ = false;
}

SpriteStore::Update SpriteStore::update(const Scene& scene, const CameraFrame& camera, double time,
                                        bool selection) {
    const std::size_t n = scene.entities.size();
    const std::uint64_t now = ++updates_;
    if (keys_.size() != n) {
        // A new entity count: every sprite afresh (keys of modelUid 0 never match).
        keys_.assign(n, EntityKey{});
        constants_.resize(n);
        changedAt_.assign(n, 0);
        posedAt_.assign(n, 0);
        changed_.resize(n);
        reposed_.resize(n);
        visible_.resize(n);
        depths_.resize(n);
        selection_.resize(n);
        valid_ = false;
    }
    // Constants depend on the light and the voxel size; sprites on those, sigma, the view mode
    // and the camera.
    const bool constantsKept =
        valid_ && sameLight(light_, scene.light) && params_.voxelSize == scene.render.voxelSize;
    const bool spritesKept =
        constantsKept && sameParams(params_, scene.render) && sameCamera(camera_, camera);
    if (!spritesKept) allChangedAt_ = now;
    // The last update's array, before writableSprites picks this update's. Not a share: that
    // would keep writableSprites from picking it again when no frame holds it. It outlives the
    // update: writableSprites drops only the oldest array, never the newest.
    const std::vector<SpriteSetup>* last =
        arrays_.empty() ? nullptr : arrays_[current_].array.get();
    const std::uint64_t lastAsOf = arrays_.empty() ? 0 : arrays_[current_].asOf;
    Sprites& into = writableSprites(n);
    std::vector<SpriteSetup>& sprites = *into.array;
    const std::uint64_t asOf = into.asOf;
    // An array a few updates old (frames in flight held the newer ones) takes the sprites that
    // changed since its stamp from the last update's array, where they are already set up as
    // they are now: those of entities this update leaves as they were, when nothing else changed
    // this update. A copy of 640 bytes in place of a set-up (with a still camera and a moving
    // entity, it was set up once per array kept); an animation step alone is cheaper still
    // (restepSprite, below).
    const std::vector<SpriteSetup>* copyFrom = last && last != into.array.get() &&
                                                       lastAsOf + 1 == now && allChangedAt_ < now &&
                                                       last->size() == n
                                                   ? last
                                                   : nullptr;

    struct Counts {
        int culled = 0, recomputed = 0, entitiesChanged = 0;
    };
    // What the per-entity checks ask of an entity's model frame, asked once per model frame
    // here: the skip rule's answer and the frame's size. Asked per entity, the bounds-checked
    // lookups and the rule's arithmetic were ~5 % of a moving 100,000-tank update's samples on
    // two cores (a scene has a few models, each a few frames).
    modelFirstFrame_.resize(scene.models.size());
    modelFrames_.clear();
    for (std::size_t m = 0; m < scene.models.size(); ++m) {
        const VoxelModel& model = *scene.models[m];
        modelFirstFrame_[m] = modelFrames_.size();
        for (int f = 0; f < model.frameCount(); ++f)
            modelFrames_.push_back(
                {model.frame(f).dims(), model.bricks(f).worthSkipping() ? 1u : 0u});
    }
    // Chunks of at most 64 entities (a sprite's set-up is 0.5-1 us, so a chunk is tens of us, far
    // above TBB's overhead): the 2,000 tanks of the bench are 32 tasks, enough for 16 cores
    // (chunks of 1024 were 2 tasks, and on the H200's host set-up took 0.52 ms, two cores'
    // worth). The auto partitioner splits no finer than it must, so 100,000 stay a few dozen.
    // The stamps read as a consumer of the history reads them (SpriteHistory): one rule for
    // when a sprite last changed, here and there.
    const SpriteHistory stamps{id_, now, {}, changedAt_, posedAt_, allChangedAt_};
    const Counts counts = tbb::parallel_reduce(
        tbb::blocked_range<std::size_t>(0, n, 64), Counts{},
        [&](const tbb::blocked_range<std::size_t>& range, Counts c) {
            // The sprites to set up again, several at a time (setupSpritesInto's SIMD lanes).
            std::array<SpriteSetupJob, 64> jobs;
            std::size_t queued = 0;
            const auto setUpQueued = [&] {
                setupSpritesInto(std::span(jobs.data(), queued), camera, scene.render);
                queued = 0;
            };
            for (std::size_t i = range.begin(); i != range.end(); ++i) {
                const Entity& e = scene.entities[i];
                const VoxelModel& model = *scene.models.at(std::size_t(e.model));
                const int frame = e.frameAt(model, time);
                // A model of no frames (only a default-constructed one) has no frame 0.
                if (frame >= model.frameCount())
                    throw std::out_of_range("sprite store: entity " + std::to_string(i) +
                                            "'s model " + std::to_string(e.model) +
                                            " has no frames");
                const ModelFrame& modelFrame =
                    modelFrames_[modelFirstFrame_[std::size_t(e.model)] + std::size_t(frame)];
                const EntityKey key{model.uid(),
                                    e.model,
                                    frame,
                                    e.position,
                                    e.rotation,
                                    e.scale,
                                    e.anchor.has_value(),
                                    e.anchor.value_or(glm::dvec3(0.0))};
                // An edit of the model can change the skip rule's answer without changing the
                // key (asked afresh each update, above).
                const std::uint32_t skipEmpty = modelFrame.skipEmpty;
                const bool entityChanged =
                    !constantsKept || !(keys_[i] == key) || constants_[i].skipEmpty != skipEmpty;
                if (entityChanged) {
                    // An animation step alone (the same entity, another frame of the same size),
                    // or a new answer of the skip rule, leaves the pose and the face lights as
                    // they are: both depend on the frame only through its size. An animated crowd
                    // steps every entity a few times a second; each step recomputed both (a
                    // rotation matrix, six light factors) and set the whole sprite up again.
                    SpriteConstants& k = constants_[i];
                    EntityKey stepped = keys_[i];
                    stepped.frame = frame;
                    if (constantsKept && stepped == key && modelFrame.dims == k.dims) {
                        k.frame = frame;
                        k.skipEmpty = skipEmpty;
                    } else {
                        k = spriteConstants(e, model, frame, scene.render, scene.light);
                        posedAt_[i] = now;
                    }
                    keys_[i] = key;
                    changedAt_[i] = now;
                    ++c.entitiesChanged;
                }
                // This array is as of update asOf: set up again what changed since. A sprite whose
                // pose and camera are as they were then changed only its frame and skip rule:
                // those two fields (with a still camera, the animated crowd's steps, and their
                // copies into the arrays that frames in flight held, cost 64 MB each at 100,000).
                if (stamps.spriteChangedAt(std::uint32_t(i)) > asOf) {
                    if (stamps.spritePosedAt(std::uint32_t(i)) <= asOf) {
                        restepSprite(sprites[i], constants_[i]);
                    } else if (copyFrom && changedAt_[i] < now) {
                        sprites[i] = (*copyFrom)[i];
                    } else {
                        // Its job writes the entity's visibility and depth too. Both change only
                        // with the pose or the camera (reposed), and a reposed entity's sprite is
                        // always set up here (neither restepped nor copied); the others keep
                        // theirs (a still camera's update read a line of every sprite for them,
                        // 6.4 MB at 100,000).
                        jobs[queued++] = {.sprite = &sprites[i],
                                          .constants = &constants_[i],
                                          .entityId = std::uint32_t(i),
                                          .selection = selection ? &selection_[i] : nullptr,
                                          .visible = &visible_[i],
                                          .depth = &depths_[i]};
                        if (queued == jobs.size()) setUpQueued();
                    }
                }
                const bool recompute = entityChanged || !spritesKept;
                c.recomputed += recompute;
                changed_[i] = recompute;
                reposed_[i] = !spritesKept || (entityChanged && posedAt_[i] == now);
            }
            setUpQueued();
            for (std::size_t i = range.begin(); i != range.end(); ++i) {
                // After updates that kept no selection inputs, every entity's afresh (the set-up's
                // jobs wrote the same values for theirs).
                if (selection && !selectionCurrent_)
                    selection_[i] = voxtier::selectionInputs(sprites[i]);
                c.culled += !visible_[i];
            }
            return c;
        },
        [](Counts a, const Counts& b) {
            a.culled += b.culled;
            a.recomputed += b.recomputed;
            a.entitiesChanged += b.entitiesChanged;
            return a;
        });
    std::vector<std::uint32_t>& visibleIds = visibleIds_.fresh();
    for (std::size_t i = 0; i < n; ++i)
        if (visible_[i]) visibleIds.push_back(std::uint32_t(i));
    into.asOf = now;
    selectionCurrent_ = selection;
    valid_ = true;
    camera_ = camera;
    params_ = scene.render;
    light_ = scene.light;
    return {int(n), counts.culled, counts.recomputed, counts.entitiesChanged};
}

} // namespace voxtier
