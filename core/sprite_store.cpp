#include "core/sprite_store.hpp"

#include <tbb/blocked_range.h>
#include <tbb/parallel_reduce.h>

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

} // namespace

void SpriteStore::clear() {
    keys_.clear();
    constants_.clear();
    sprites_.writable().clear();
    changed_.clear();
    visible_.clear();
    visibleIds_.writable().clear();
    valid_ = false;
}

SpriteStore::Update SpriteStore::update(const Scene& scene, const CameraFrame& camera,
                                        double time) {
    const std::size_t n = scene.entities.size();
    std::vector<SpriteSetup>& sprites = sprites_.writable();
    if (keys_.size() != n) {
        // A new entity count: every sprite afresh (keys of modelUid 0 never match).
        keys_.assign(n, EntityKey{});
        constants_.resize(n);
        sprites.resize(n);
        changed_.resize(n);
        visible_.resize(n);
        valid_ = false;
    }
    // Constants depend on the light and the voxel size; sprites on those, sigma, the view mode
    // and the camera.
    const bool constantsKept =
        valid_ && sameLight(light_, scene.light) && params_.voxelSize == scene.render.voxelSize;
    const bool spritesKept =
        constantsKept && sameParams(params_, scene.render) && sameCamera(camera_, camera);

    struct Counts {
        int culled = 0, recomputed = 0, entitiesChanged = 0;
    };
    // Chunks of 1024 entities: enough work per task that TBB's overhead vanishes, and enough
    // chunks to keep every core busy.
    const Counts counts = tbb::parallel_reduce(
        tbb::blocked_range<std::size_t>(0, n, 1024), Counts{},
        [&](const tbb::blocked_range<std::size_t>& range, Counts c) {
            for (std::size_t i = range.begin(); i != range.end(); ++i) {
                const Entity& e = scene.entities[i];
                const VoxelModel& model = *scene.models.at(std::size_t(e.model));
                const int frame = e.frameAt(model, time);
                const EntityKey key{model.uid(),
                                    e.model,
                                    frame,
                                    e.position,
                                    e.rotation,
                                    e.scale,
                                    e.anchor.has_value(),
                                    e.anchor.value_or(glm::dvec3(0.0))};
                // An edit of the model can change the skip rule's answer without changing the
                // key (BrickOccupancy::worthSkipping is O(1)).
                const std::uint32_t skipEmpty = model.bricks(frame).worthSkipping() ? 1u : 0u;
                const bool entityChanged =
                    !constantsKept || !(keys_[i] == key) || constants_[i].skipEmpty != skipEmpty;
                if (entityChanged) {
                    keys_[i] = key;
                    constants_[i] = spriteConstants(e, model, frame, scene.render, scene.light);
                    ++c.entitiesChanged;
                }
                const bool recompute = entityChanged || !spritesKept;
                if (recompute) {
                    setupSpriteInto(sprites[i], camera, constants_[i], std::uint32_t(i),
                                    scene.render);
                    ++c.recomputed;
                }
                changed_[i] = recompute;
                visible_[i] = sprites[i].visible();
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
    std::vector<std::uint32_t>& visibleIds = visibleIds_.writable();
    visibleIds.clear();
    for (std::size_t i = 0; i < n; ++i)
        if (visible_[i]) visibleIds.push_back(std::uint32_t(i));
    valid_ = true;
    camera_ = camera;
    params_ = scene.render;
    light_ = scene.light;
    return {int(n), counts.culled, counts.recomputed, counts.entitiesChanged};
}

} // namespace voxtier
