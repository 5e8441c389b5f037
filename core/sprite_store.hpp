#pragma once
// The frame's sprites, kept from one frame to the next (the set-up step of the frame recipe).
// A frame asks for every entity's SpriteSetup; most of it does not change between frames:
// the entity's pose and face lights change only when the entity moves, turns or steps to an
// animation frame of another size (or the light changes), and nothing of a sprite changes while
// neither its entity nor the camera does. So the store keeps, per entity, what set-up derives from
// the entity alone (SpriteConstants) and the sprite itself, and an update recomputes only what
// changed: the constants of the entities that changed, and the sprites of those entities, or of
// every entity when the camera moved. An animation step to a frame of the same size, or a new
// answer of the skip rule, changes two fields of a sprite, and only those are written
// (restepSprite). The arrays grow with the entity count and are reused: an update
// allocates nothing once the scene's entities are known, and runs in parallel (TBB).
//
// A frame's result shares the sprites it drew (shareSprites), and a path render keeps frames in
// flight, so the array the last frame drew is usually still held when the next update comes.
// Rather than copy it (64 MB at 100,000 entities), the store keeps a few arrays in turn, each
// stamped with the update it is as of, and brings the one no frame holds up to date: the sprites
// of the entities that changed since its stamp (every sprite when the camera moved since),
// copied from the last update's array where this update changed neither them nor the camera.
//
// Every sprite equals a fresh setupSprite() of its entity bit for bit: the store decides when to
// set a sprite up, and sets the ones it must up several at a time on SIMD lanes (setupSpritesInto,
// the same operations in the same order as the scalar setupSpriteInto).
#include "core/camera.hpp"
#include "core/process_uid.hpp"
#include "core/scene.hpp"
#include "core/shared_vector.hpp"
#include "core/sprite.hpp"

#include <algorithm>
#include <cstdint>
#include <memory>
#include <optional>
#include <span>
#include <vector>

namespace voxtier {

/// What a consumer that keeps something of the sprites between frames (the Vulkan near tier's
/// records, its draw order) needs to tell which sprites are as they were: one update's array of
/// one store, and per entity the updates that last changed its sprite (SpriteStore::history).
/// A copy made from this array at update T is still current for an entity whose sprite changed
/// at T or before.
struct SpriteHistory {
    std::uint64_t store = 0;              ///< which store: unique in the process (0: no history)
    std::uint64_t now = 0;                ///< this update
    std::span<const SpriteSetup> sprites; ///< this update's array, by entity id
    /// Per entity id, the update that last changed its sprite in any field, and in more than its
    /// animation frame and skip rule (its depth, rectangle, visibility...); allChangedAt: every
    /// sprite's (the camera, the render parameters, the light, the entity count).
    std::span<const std::uint64_t> changedAt, posedAt;
    std::uint64_t allChangedAt = 0;
    /// Per entity id, whether this update's sprite is visible (SpriteSetup::visible) and its
    /// billboard depth (SpriteSetup::gpu.depth): what a draw order reads, 5 bytes an entity in
    /// place of two cache lines of its 640-byte sprite (at 100,000 moving sprites the reads of
    /// the sprites were half of the near tier's order). Empty where not kept.
    std::span<const std::uint8_t> visible;
    std::span<const float> depths;
    /// Whether `visible` and `depths` describe `sprites` (a store's history does; one built by
    /// hand may leave them empty).
    bool hasDepths() const {
        return visible.size() == sprites.size() && depths.size() == sprites.size();
    }

    /// What a consumer that keeps things per entity records for a sprite that is no store's (a
    /// copy, a cross-fade's) or drawn with no history.
    static constexpr std::uint32_t kNoEntity = 0xFFFFFFFFu;
    /// entityOf through a history that may be absent: kNoEntity for none, or for a copy.
    static std::uint32_t entityIn(const SpriteHistory* history, const SpriteSetup* s) {
        return history ? history->entityOf(s).value_or(kNoEntity) : kNoEntity;
    }

    /// What a draw order reads of sprite `s`, and the entity whose sprite it is through `history`
    /// (kNoEntity: none, or a copy). For the store's own sprite, where the history keeps its
    /// per-entity arrays, visibility, depth and id come from those (the sprite's lines are not
    /// read); else from the sprite.
    struct OrderInputs {
        bool visible = false;
        float depth = 0.0f;
        std::uint32_t id = 0;
        std::uint32_t entity = kNoEntity;
    };
    static OrderInputs orderInputs(const SpriteHistory* history, const SpriteSetup& s) {
        const std::uint32_t e = entityIn(history, &s);
        if (e != kNoEntity && history->hasDepths())
            return {history->visible[e] != 0, history->depths[e], e, e};
        return {s.visible(), s.gpu.depth, s.entityId, e};
    }

    /// The entity whose sprite `s` is, when `s` points into `sprites` (not at a copy): its index
    /// there, which is its SpriteSetup::entityId.
    std::optional<std::uint32_t> entityOf(const SpriteSetup* s) const {
        const auto at = reinterpret_cast<std::uintptr_t>(s),
                   begin = reinterpret_cast<std::uintptr_t>(sprites.data());
        if (store == 0 || at < begin || at >= begin + sprites.size_bytes()) return std::nullopt;
        return std::uint32_t((at - begin) / sizeof(SpriteSetup));
    }
    /// The update that last changed any field of entity `e`'s sprite.
    std::uint64_t spriteChangedAt(std::uint32_t e) const {
        return std::max(changedAt[e], allChangedAt);
    }
    /// The update that last changed more of it than its animation frame and skip rule.
    std::uint64_t spritePosedAt(std::uint32_t e) const {
        return std::max(posedAt[e], allChangedAt);
    }
};

class SpriteStore {
  public:
    /// What one update did.
    struct Update {
        int entities = 0;
        int culled = 0;     ///< sprites that draw nothing this frame (SpriteSetup::cull)
        int recomputed = 0; ///< sprites that changed since the last update (the others did not)
        int entitiesChanged = 0; ///< of those, entities whose constants changed (or are new)
    };

    /// Brings every entity's sprite up to date for `camera` at `time` (animation frames).
    /// `selection`: keep selectionInputs() too (false where no frame plans from this update: a
    /// near or reference frame spares writing 96 bytes an entity it does not read).
    Update update(const Scene& scene, const CameraFrame& camera, double time,
                  bool selection = true);
    /// Forgets everything: the next update sets every sprite up afresh.
    void clear();

    /// Per entity id, as of the last update.
    std::span<const SpriteSetup> sprites() const;
    /// The same, shared: it stays as it is when later updates change the store's sprites.
    SharedVector<SpriteSetup> shareSprites() const;
    /// The ids of the visible sprites (SpriteSetup::visible), ascending.
    std::span<const std::uint32_t> visibleIds() const { return visibleIds_.read(); }
    /// The same, shared with a frame still in flight (copied by the next update only then).
    SharedVector<std::uint32_t> shareVisibleIds() const { return visibleIds_.share(); }
    /// Per entity id: 1 where the last update set the sprite up afresh, 0 where it is the one
    /// before (what a consumer that mirrors the sprites elsewhere has to refresh).
    std::span<const std::uint8_t> changed() const { return changed_; }
    /// Per entity id: 1 where the last update changed the sprite in more than its animation frame
    /// and skip rule (restepSprite), 0 where only those or nothing changed: what a consumer that
    /// reads neither has to refresh (the frame planner: a still crowd's animation step changes
    /// every sprite and no plan).
    std::span<const std::uint8_t> reposed() const { return reposed_; }
    /// Per entity id, selectionInputs of the last update's sprite: what the LOD plan reads of it
    /// (FramePlanner::plan), 96 bytes in place of three or four lines of the sprite. Rewritten
    /// where the update set the sprite up (nothing else it holds changes); empty after an update
    /// told not to keep them.
    std::span<const SpriteSelectionInputs> selectionInputs() const {
        return selectionCurrent_ ? std::span<const SpriteSelectionInputs>(selection_)
                                 : std::span<const SpriteSelectionInputs>();
    }
    /// The last update's sprites with the updates that changed each (SpriteHistory): valid until
    /// the next update.
    SpriteHistory history() const;

    SpriteStore() = default;
    /// Not copied or moved: a history names its store (SpriteHistory::store), and two stores
    /// under one name would pass each other's sprites off as current.
    SpriteStore(const SpriteStore&) = delete;
    SpriteStore& operator=(const SpriteStore&) = delete;

  private:
    /// What a sprite's constants depend on, besides the light and the render parameters.
    struct EntityKey {
        std::uint64_t modelUid = 0; ///< 0: not set up yet
        int model = 0;
        int frame = 0;
        glm::dvec3 position{0.0};
        glm::dquat rotation{1.0, 0.0, 0.0, 0.0};
        double scale = 1.0;
        bool hasAnchor = false;
        glm::dvec3 anchor{0.0};
        bool operator==(const EntityKey&) const = default;
    };

    /// One array of sprites, as of update `asOf` (0: none yet).
    struct Sprites {
        std::shared_ptr<std::vector<SpriteSetup>> array;
        std::uint64_t asOf = 0;
    };
    /// The array the next update writes: one no share holds, the most recent such, or a new one.
    Sprites& writableSprites(std::size_t n);

    /// Per model frame, what the per-entity checks read of it, asked once an update: its size and
    /// the skip rule's answer (BrickOccupancy::worthSkipping). Frame f of model m is at
    /// modelFrames_[modelFirstFrame_[m] + f].
    struct ModelFrame {
        glm::ivec3 dims{0};
        std::uint32_t skipEmpty = 0;
    };
    std::vector<ModelFrame> modelFrames_;
    std::vector<std::size_t> modelFirstFrame_;

    std::vector<EntityKey> keys_;
    std::vector<SpriteConstants> constants_;
    /// The arrays in turn (at most kSpriteArrays kept); current_ is the last update's.
    std::vector<Sprites> arrays_;
    std::size_t current_ = 0;
    std::uint64_t updates_ = 0; ///< updates so far: the stamp of the last one
    /// Which store this is, for SpriteHistory (a copy takes a new one).
    std::uint64_t id_ = newProcessUid();
    /// Per entity, the update that last changed its sprite; every sprite's, for the camera,
    /// sigma, view mode, light or entity count.
    std::vector<std::uint64_t> changedAt_;
    /// Per entity, the update that last changed more of it than its animation frame and skip rule
    /// (its pose, size or light): a sprite set up since, and since the camera last moved, needs
    /// only those two fields brought up to date (restepSprite).
    std::vector<std::uint64_t> posedAt_;
    std::uint64_t allChangedAt_ = 0;
    std::vector<std::uint8_t> changed_, reposed_, visible_;
    std::vector<float> depths_;                    ///< SpriteHistory::depths
    std::vector<SpriteSelectionInputs> selection_; ///< selectionInputs()
    /// selection_ holds every entity's inputs as of the last update (it was told to keep them,
    /// and so was every update since the last that was not).
    bool selectionCurrent_ = false;
    SharedVectorOwner<std::uint32_t> visibleIds_;
    /// What every sprite of the last update was set up with.
    bool valid_ = false;
    CameraFrame camera_{};
    RenderParams params_{};
    Light light_{};
};

} // namespace voxtier
