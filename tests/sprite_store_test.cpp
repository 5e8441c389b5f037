// The sprite store (core/sprite_store.hpp): sprites kept between frames equal a fresh set-up of
// every entity, bit for bit, and an update sets up afresh exactly what changed: nothing under a
// still camera, the entities that stepped to another animation frame or moved, everything when
// the camera or the light moves. A frame's share of the sprites stays as it was.
#include "core/model_view.hpp"
#include "core/near_rate.hpp"
#include "core/occlusion.hpp"
#include "core/procedural.hpp"
#include "core/scene_loader.hpp"
#include "core/sprite_store.hpp"
#include "source_tree.hpp"
#include "sprite_compare.hpp"
#include "test_models.hpp"
#include "view_sweeps.hpp"

#include <gtest/gtest.h>

#include <bit>

namespace voxtier {
namespace {

using test::sameSprite;
using test::sourcePath;

/// Every sprite of the store against a fresh set-up of its entity.
void expectFresh(const SpriteStore& store, const Scene& s, const CameraFrame& cam, double t) {
    const std::vector<SpriteSetup> fresh = setupSprites(s, cam, t);
    ASSERT_EQ(store.sprites().size(), fresh.size());
    std::size_t visible = 0;
    for (std::size_t i = 0; i < fresh.size(); ++i) {
        ASSERT_TRUE(sameSprite(store.sprites()[i], fresh[i])) << " at t " << t;
        visible += fresh[i].visible();
    }
    ASSERT_EQ(store.visibleIds().size(), visible);
    for (const std::uint32_t i : store.visibleIds()) EXPECT_TRUE(fresh[i].visible());
    // The history's per-entity arrays, which a draw order reads in place of the sprites.
    const SpriteHistory h = store.history();
    ASSERT_EQ(h.visible.size(), fresh.size());
    ASSERT_EQ(h.depths.size(), fresh.size());
    for (std::size_t i = 0; i < fresh.size(); ++i) {
        ASSERT_EQ(h.visible[i] != 0, fresh[i].visible()) << "entity " << i << " at t " << t;
        EXPECT_EQ(fresh[i].entityId, i);
        if (fresh[i].visible()) {
            ASSERT_EQ(std::bit_cast<std::uint32_t>(h.depths[i]),
                      std::bit_cast<std::uint32_t>(fresh[i].gpu.depth))
                << "entity " << i << " at t " << t;
        }
    }
    // The selection inputs, which a plan reads in place of the sprites: the sizes the cost bound
    // prices a sprite by too (a visible sprite's cells and rectangle as near_rate counts them).
    ASSERT_EQ(store.selectionInputs().size(), fresh.size());
    for (std::size_t i = 0; i < fresh.size(); ++i) {
        const SpriteSelectionInputs& in = store.selectionInputs()[i];
        ASSERT_TRUE(test::sameSelection(in, selectionInputs(fresh[i])))
            << "entity " << i << " at t " << t;
        if (fresh[i].visible()) {
            ASSERT_EQ(in.cells, cellCount(fresh[i])) << "entity " << i << " at t " << t;
            ASSERT_EQ(in.rectPixels, rectPixels(fresh[i])) << "entity " << i << " at t " << t;
        }
    }
}

/// The bench crowd: 800 entities, 40 of them animated (2 frames a second), a camera path.
Scene crowd() {
    return loadScene(sourcePath("scenes/bench/vox_crowd.json"));
}

TEST(SpriteStore, EverySpriteEqualsAFreshSetUpAlongAPath) {
    const Scene s = crowd();
    SpriteStore store;
    for (int f = 0; f < 24; f += 3) {
        const double t = s.timeOfFrame(f);
        const CameraFrame cam = makeCameraFrame(s.cameraAt(t));
        const SpriteStore::Update u = store.update(s, cam, t);
        EXPECT_EQ(u.entities, int(s.entities.size()));
        EXPECT_EQ(u.recomputed, u.entities) << "the camera moved: every sprite is new";
        expectFresh(store, s, cam, t);
    }
}

// The draw order read through the history (its per-entity visibility and depths) is the order
// read from the sprites, along a path, under a still camera, and with copies of some sprites
// (a cross-fade's, at other depths) among the store's: those are read from the copy.
TEST(SpriteStore, TheDrawOrderFromTheHistoryIsTheOrderFromTheSprites) {
    const Scene s = crowd();
    SpriteStore store;
    DrawOrderBuffers withHistory, without;
    std::vector<std::uint32_t> a, b;
    for (const double t : {0.0, 0.1, 0.2, 0.2, 1.3}) {
        store.update(s, makeCameraFrame(s.cameraAt(t < 1.0 ? t : 0.2)), t);
        const SpriteHistory h = store.history();
        std::vector<const SpriteSetup*> all;
        for (const SpriteSetup& sp : store.sprites()) all.push_back(&sp);
        std::vector<SpriteSetup> copies(store.sprites().begin(), store.sprites().begin() + 40);
        for (std::size_t k = 0; k < copies.size(); k += 2) {
            copies[k].gpu.depth *= 0.5f;
            all[k] = &copies[k];
        }
        all[41] = nullptr;
        frontToBack(all, withHistory, a, &h);
        frontToBack(all, without, b);
        EXPECT_GT(a.size(), 100u);
        EXPECT_TRUE(a == b) << "at t " << t;
    }
}

TEST(SpriteStore, AStillCameraSetsUpOnlyTheEntitiesThatChangedFrame) {
    const Scene s = crowd();
    const CameraFrame cam = makeCameraFrame(s.cameraAt(0.0));
    SpriteStore store;
    EXPECT_EQ(store.update(s, cam, 0.0).recomputed, int(s.entities.size()));
    const SpriteStore::Update same = store.update(s, cam, 0.0);
    EXPECT_EQ(same.recomputed, 0);
    EXPECT_EQ(same.entitiesChanged, 0);
    for (const std::uint8_t c : store.changed()) EXPECT_EQ(c, 0);
    // Later, the animated entities (2 frames a second) have stepped on, the others not.
    for (const double t : {0.6, 1.3, 2.9}) {
        int stepped = 0;
        std::vector<int> before(s.entities.size());
        for (std::size_t i = 0; i < s.entities.size(); ++i) before[i] = store.sprites()[i].frame;
        const SpriteStore::Update u = store.update(s, cam, t);
        for (std::size_t i = 0; i < s.entities.size(); ++i) {
            const Entity& e = s.entities[i];
            const int now = e.frameAt(*s.models[std::size_t(e.model)], t);
            stepped += now != before[i];
            EXPECT_EQ(store.changed()[i], now != before[i] ? 1 : 0) << "entity " << i;
        }
        EXPECT_GT(stepped, 0) << "the crowd's animated entities step on between these times";
        EXPECT_EQ(u.recomputed, stepped);
        EXPECT_EQ(u.entitiesChanged, stepped);
        expectFresh(store, s, cam, t);
    }
}

// Updates told to keep no selection inputs (near and reference frames) lend none; the next update
// that keeps them has every entity's, those it set up and those it left as they were, moved
// entities among them, whether the camera moved or not.
TEST(SpriteStore, SelectionInputsAfterUpdatesThatKeptNoneAreEveryEntitys) {
    Scene s = crowd();
    SpriteStore store;
    const CameraFrame still = makeCameraFrame(s.cameraAt(0.0));
    store.update(s, still, 0.0);
    expectFresh(store, s, still, 0.0);
    store.update(s, makeCameraFrame(s.cameraAt(0.5)), 0.1, false);
    EXPECT_TRUE(store.selectionInputs().empty());
    s.entities[3].position.x += 2.0;
    store.update(s, still, 0.2, false); // the camera back, an entity moved: all set up again
    EXPECT_TRUE(store.selectionInputs().empty());
    s.entities[5].position.x += 2.0;
    const SpriteStore::Update u = store.update(s, still, 0.2); // one entity set up, and kept
    EXPECT_EQ(u.entitiesChanged, 1);
    expectFresh(store, s, still, 0.2);
    const CameraFrame moved = makeCameraFrame(s.cameraAt(1.0));
    store.update(s, moved, 0.3, false);
    store.update(s, moved, 0.3); // nothing set up, and kept
    expectFresh(store, s, moved, 0.3);
}

TEST(SpriteStore, AMovedEntityAndANewLightAreSetUpAfresh) {
    Scene s = crowd();
    const CameraFrame cam = makeCameraFrame(s.cameraAt(0.0));
    SpriteStore store;
    store.update(s, cam, 0.0);
    s.entities[17].position += glm::dvec3(0.5, 0.0, -0.25);
    s.entities[400].rotation = glm::angleAxis(0.7, glm::dvec3(0.0, 1.0, 0.0));
    const SpriteStore::Update moved = store.update(s, cam, 0.0);
    EXPECT_EQ(moved.recomputed, 2);
    EXPECT_EQ(store.changed()[17], 1);
    EXPECT_EQ(store.changed()[400], 1);
    expectFresh(store, s, cam, 0.0);

    s.light.direction = {0.2, 1.0, -0.3};
    EXPECT_EQ(store.update(s, cam, 0.0).recomputed, int(s.entities.size()));
    expectFresh(store, s, cam, 0.0);

    s.render.sigma = 2.0;
    EXPECT_EQ(store.update(s, cam, 0.0).recomputed, int(s.entities.size()));
    expectFresh(store, s, cam, 0.0);

    s.entities.pop_back(); // a new entity count: everything afresh
    EXPECT_EQ(store.update(s, cam, 0.0).recomputed, int(s.entities.size()));
    expectFresh(store, s, cam, 0.0);
}

TEST(SpriteStore, AShareOfTheSpritesKeepsItsFrame) {
    const Scene s = crowd();
    SpriteStore store;
    const CameraFrame first = makeCameraFrame(s.cameraAt(0.0));
    store.update(s, first, 0.0);
    const SharedVector<SpriteSetup> kept = store.shareSprites();
    const double later = s.timeOfFrame(20);
    const CameraFrame second = makeCameraFrame(s.cameraAt(later));
    store.update(s, second, later);
    const std::vector<SpriteSetup> fresh = setupSprites(s, first, 0.0);
    ASSERT_EQ(kept.size(), fresh.size());
    for (std::size_t i = 0; i < fresh.size(); ++i) ASSERT_TRUE(sameSprite(kept[i], fresh[i]));
    expectFresh(store, s, second, later);
}

// An animation step keeps the entity's pose and face lights only where the new frame has the old
// one's size: the default anchor is the frame's bottom centre, so a step to a frame of another
// size moves the model. Frames 0 and 1 are 4x4x4, frame 2 is 6x4x2; entities step at 3 frames a
// second from different start frames, one with an anchor of its own, one also moving.
TEST(SpriteStore, AnAnimationStepKeepsThePoseOnlyBetweenFramesOfOneSize) {
    VoxelGrid a({4, 4, 4}), b({4, 4, 4}), c({6, 4, 2});
    for (auto& x : a.data()) x = 1;
    for (std::size_t k = 0; k < b.data().size(); k += 2) b.data()[k] = 2;
    for (auto& x : c.data()) x = 3;
    auto model =
        std::make_shared<VoxelModel>("steps", proceduralPalette(), std::vector<VoxelGrid>{a, b, c});
    Scene s = sceneForModel(model, test::viewToward({1, 2, 3}, 2.0, 96, 64));
    const Entity base = s.entities.at(0);
    s.entities.clear();
    for (int k = 0; k < 6; ++k) {
        Entity e = base;
        e.frame = k % 3;
        e.fps = 3.0;
        e.position += glm::dvec3(0.3 * k, 0.0, -0.2 * k);
        e.rotation = glm::angleAxis(0.4 * k, glm::dvec3(0.0, 1.0, 0.0));
        if (k == 4) e.anchor = glm::dvec3(1.0, 2.0, 0.5);
        s.entities.push_back(e);
    }
    const CameraFrame cam = makeCameraFrame(s.cameraAt(0.0));
    SpriteStore store;
    store.update(s, cam, 0.0);
    expectFresh(store, s, cam, 0.0);
    for (int step = 1; step <= 7; ++step) {
        const double t = step / 3.0 + 0.01; // one frame on for every entity
        s.entities[5].position.x += 0.125;  // a move and a step at once
        const SpriteStore::Update u = store.update(s, cam, t);
        EXPECT_EQ(u.entitiesChanged, 6) << "every entity stepped at t " << t;
        expectFresh(store, s, cam, t);
    }
}

// With a still camera an animation step changes only a sprite's frame and its record's skip rule
// (restepSprite); the store brings those two fields up to date in the array it writes, whatever
// update that array is as of, while frames in flight hold the newer ones. Frame 0 is a solid
// 64^3 box (its rays do not skip), frame 1 the same size with most bricks empty (they skip);
// entities visible, off the screen but in front (their records are filled), behind the camera
// and too far to cover half a pixel (both culled before the lattice), stepping at different rates.
TEST(SpriteStore, StepsUnderAStillCameraWithFramesInFlightEqualAFreshSetUp) {
    VoxelGrid solid({64, 64, 64}), shell({64, 64, 64});
    for (auto& x : solid.data()) x = 1;
    for (int z = 0; z < 64; ++z)
        for (int y = 0; y < 64; ++y) shell.set({0, y, z}, 2);
    auto model = std::make_shared<VoxelModel>("skips", proceduralPalette(),
                                              std::vector<VoxelGrid>{solid, shell});
    ASSERT_NE(model->bricks(0).worthSkipping(), model->bricks(1).worthSkipping());
    Scene s = sceneForModel(model, test::viewToward({1, 2, 3}, 1.0, 96, 64));
    const Entity base = s.entities.at(0);
    const CameraFrame cam = makeCameraFrame(s.cameraAt(0.0));
    s.entities.clear();
    for (int k = 0; k < 12; ++k) {
        Entity e = base;
        e.frame = k % 2;
        e.fps = 1.0 + k % 3;                               // steps at 1, 2 and 3 frames a second
        if (k % 4 == 1) e.position += 40.0 * cam.right;    // in front, off the screen
        if (k % 4 == 2) e.position -= 200.0 * cam.forward; // behind the camera
        if (k % 4 == 3) e.position += 1e5 * cam.forward;   // below half a pixel
        s.entities.push_back(e);
    }
    SpriteStore store;
    std::vector<SharedVector<SpriteSetup>> inFlight(2);
    bool offScreen = false, behind = false, subPixel = false, skips = false, solidSeen = false;
    for (int f = 0; f < 14; ++f) {
        const double t = f / 6.0;
        store.update(s, cam, t);
        expectFresh(store, s, cam, t);
        inFlight[std::size_t(f) % 2] =
            store.shareSprites(); // two frames held, as a path render does
        for (const SpriteSetup& sp : store.sprites()) {
            offScreen = offScreen || sp.cull == CullReason::OffScreen;
            behind = behind || sp.cull == CullReason::BehindCamera;
            subPixel = subPixel || sp.cull == CullReason::SubPixel;
            skips = skips || (sp.visible() && sp.gpu.skipEmpty == 1u);
            solidSeen = solidSeen || (sp.visible() && sp.gpu.skipEmpty == 0u);
        }
    }
    EXPECT_TRUE(offScreen && behind && subPixel && skips && solidSeen)
        << "the scene shows every case: off the screen, behind, too small, skipping and not";
}

// An edit that changes whether a model's rays skip empty space (SpriteGpu::skipEmpty, from the
// frame's brick occupancy) sets its entities up afresh, camera and entities still; an edit that
// leaves the answer as it was sets nothing up.
TEST(SpriteStore, AnEditThatTurnsEmptySpaceSkippingSetsItsEntitiesUpAfresh) {
    Scene s = sceneForModel(test::solidBox({64, 64, 64}), test::viewToward({1, 2, 3}, 1.0, 64, 48));
    VoxelModel& model = *s.models.at(0);
    const CameraFrame cam = makeCameraFrame(s.cameraAt(0.0));
    SpriteStore store;
    store.update(s, cam, 0.0);
    ASSERT_EQ(store.sprites()[0].gpu.skipEmpty, 0u) << "a solid box has no empty space";
    // A corner voxel less: still no empty brick, the same answer.
    ASSERT_TRUE(model.clearBox(0, {glm::ivec3(0), glm::ivec3(1)}));
    EXPECT_EQ(store.update(s, cam, 0.0).entitiesChanged, 0);
    // All but a shell of one voxel's thickness at one side: most bricks empty.
    ASSERT_TRUE(model.clearBox(0, {glm::ivec3(1, 0, 0), glm::ivec3(64)}));
    const SpriteStore::Update u = store.update(s, cam, 0.0);
    EXPECT_EQ(u.entitiesChanged, 1);
    EXPECT_EQ(store.changed()[0], 1);
    EXPECT_EQ(store.sprites()[0].gpu.skipEmpty, 1u);
    expectFresh(store, s, cam, 0.0);
}

// A history's stamps say which sprites are as an earlier update left them, which is what a
// consumer that keeps copies (the Vulkan near tier's records and draw order) relies on: at every
// update, for every earlier update T with a copy kept, each entity whose sprite changed at T or
// before has the copy's sprite bit for bit, and each one not set up anew since T the copy's but
// for its animation frame and skip rule. Animation steps, moved entities, camera moves and a light
// change, with frames in flight holding arrays; a copy's pointer is no entity's, and two stores
// have two names. Stamps that lag a change fail the first check; a history whose posed stamps
// were the animation steps' would pass it, and fails the count of kept sprites below.
TEST(SpriteStore, AHistoryNamesTheSpritesThatChangedSinceAnyEarlierUpdate) {
    Scene s = crowd();
    s.path.reset(); // a still camera, but where the test moves it
    SpriteStore store;
    struct Copy {
        std::uint64_t asOf = 0;
        std::vector<SpriteSetup> sprites;
    };
    std::vector<Copy> copies;
    std::vector<SharedVector<SpriteSetup>> inFlight;
    std::size_t keptWhole = 0, keptPose = 0;
    CameraFrame cam = makeCameraFrame(s.cameraAt(0.0));
    for (int u = 0; u < 24; ++u) {
        const double t = 0.25 * u; // the animated entities step at 2 frames a second
        if (u == 7 || u == 15) s.entities[std::size_t(u) * 11].position.x += 0.3;
        if (u == 10) {
            s.camera.position += glm::dvec3(0.1, 0.0, 0.05);
            cam = makeCameraFrame(s.cameraAt(t));
        }
        if (u == 19) s.light.direction = {0.3, 1.0, -0.2};
        store.update(s, cam, t);
        inFlight.push_back(store.shareSprites());
        if (inFlight.size() > 2) inFlight.erase(inFlight.begin());
        const SpriteHistory h = store.history();
        ASSERT_NE(h.store, 0u);
        ASSERT_EQ(h.sprites.data(), store.sprites().data());
        for (const Copy& c : copies)
            for (std::uint32_t e = 0; e < h.sprites.size(); ++e) {
                const SpriteSetup& now = h.sprites[e];
                const SpriteSetup& then = c.sprites[e];
                if (h.spriteChangedAt(e) <= c.asOf) {
                    ASSERT_TRUE(test::sameSprite(now, then))
                        << "update " << u << " copy " << c.asOf;
                    ++keptWhole;
                }
                if (h.spritePosedAt(e) <= c.asOf) {
                    // Everything but the animation frame and the skip rule (restepSprite).
                    SpriteSetup stepped = then;
                    stepped.frame = now.frame;
                    stepped.gpu.skipEmpty = now.gpu.skipEmpty;
                    ASSERT_TRUE(test::sameSprite(now, stepped))
                        << "update " << u << " copy " << c.asOf;
                    keptPose += h.spriteChangedAt(e) > c.asOf;
                }
                ASSERT_EQ(h.entityOf(&now), std::optional<std::uint32_t>(e));
            }
        copies.push_back({h.now, std::vector<SpriteSetup>(h.sprites.begin(), h.sprites.end())});
        ASSERT_FALSE(h.entityOf(&copies.back().sprites[3]).has_value()) << "a copy is no entity";
    }
    // Most sprites outlive most copies; the animated ones that stepped keep their pose.
    EXPECT_GT(keptWhole, std::size_t(s.entities.size()) * 24);
    EXPECT_GT(keptPose, 0u);
    SpriteStore other;
    other.update(s, cam, 0.0);
    EXPECT_NE(other.history().store, store.history().store);
}

} // namespace
} // namespace voxtier
