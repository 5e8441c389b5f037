// The snapshot cache (CONTRACT.md §4): lazy, shared by every entity of a model, one bake under
// concurrent requests, LRU eviction within a byte budget, a model edit (version bump) misses.
#include "core/procedural.hpp"
#include "core/splitmix64.hpp"
#include "far_test_support.hpp"

#include <gtest/gtest.h>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include <algorithm>
#include <atomic>
#include <map>
#include <set>
#include <stdexcept>
#include <tuple>

namespace voxtier {
namespace {

TEST(SnapshotCache, NothingIsBakedUntilAViewIsRequested) {
    const auto m = makeSphere(5);
    SnapshotCache cache;
    const SnapshotKey key{m->uid(), 0, m->version(), viewIdOf(ViewSet::Cube26, 7), 1.0};
    EXPECT_EQ(cache.counters().bakes, 0u);
    EXPECT_EQ(cache.counters().scenesBuilt, 0u);
    EXPECT_EQ(cache.find(key), nullptr);
    const auto s = cache.get(*m, 0, ViewSet::Cube26, 7, 1.0);
    ASSERT_NE(s, nullptr);
    EXPECT_EQ(s->view, viewIdOf(ViewSet::Cube26, 7));
    EXPECT_EQ(cache.find(key), s);
    const auto c = cache.counters();
    EXPECT_EQ(c.bakes, 1u);
    EXPECT_EQ(c.misses, 1u);
    EXPECT_EQ(c.hits, 0u);
    EXPECT_EQ(c.scenesBuilt, 1u);
    EXPECT_EQ(c.raysTraced, std::uint64_t(s->width()) * std::uint64_t(s->height()));
    EXPECT_EQ(c.bytes, s->bytes());
    // Every other view reuses the model frame's Embree scene.
    for (int v = 0; v < 26; ++v) cache.get(*m, 0, ViewSet::Cube26, v, 1.0);
    EXPECT_EQ(cache.counters().bakes, 26u);
    EXPECT_EQ(cache.counters().scenesBuilt, 1u);
}

// One frame with 100 entities of one model, all seen along the same direction (parallel view
// mode, camera looking exactly along -Y of the models): one bake, shared by all 100.
TEST(SnapshotCache, HundredEntitiesOfOneModelShareOneBake) {
    const Scene s = test::hundredEntityWall(makeArrow(16), -30.0);
    SnapshotCache cache;
    std::vector<SpriteSetup> sp;
    const Image img = test::renderFar(s, cache, ViewSet::Cube26, &sp);
    int visible = 0;
    for (const auto& x : sp) visible += x.visible();
    EXPECT_EQ(visible, 100);
    EXPECT_EQ(cache.counters().bakes, 1u);
    for (std::uint32_t i = 0; i < 100; ++i) EXPECT_GT(img.countEntity(i), 0u) << i;
    test::renderFar(s, cache); // a second frame: a hit, no bake
    EXPECT_EQ(cache.counters().bakes, 1u);
    EXPECT_EQ(cache.counters().hits, 1u);
}

// Hammered from TBB tasks: 3 distinct keys, 3000 requests, 3 bakes, one pointer per key.
TEST(SnapshotCache, ConcurrentRequestsForOneKeyBakeOnce) {
    const auto m = makeSphere(12);
    SnapshotCache cache;
    std::vector<const Snapshot*> got(3000);
    tbb::parallel_for(0, 3000, [&](int i) {
        got[std::size_t(i)] = cache.get(*m, 0, ViewSet::Cube26, 18 + i % 3, 2.0).get();
    });
    const auto c = cache.counters();
    EXPECT_EQ(c.bakes, 3u);
    EXPECT_EQ(c.misses, 3u);
    EXPECT_EQ(c.hits, 2997u);
    EXPECT_EQ(c.scenesBuilt, 1u);
    std::set<const Snapshot*> distinct(got.begin(), got.end());
    EXPECT_EQ(distinct.size(), 3u);
    for (int i = 0; i < 3000; ++i)
        EXPECT_EQ(got[std::size_t(i)]->view, viewIdOf(ViewSet::Cube26, 18 + i % 3));
}

TEST(SnapshotCache, ConcurrentRequestsAcrossModelsAndViewsBakeEachKeyOnce) {
    std::vector<std::shared_ptr<VoxelModel>> models = {makeSphere(6), makeArrow(20),
                                                       makeBox({5, 7, 9})};
    SnapshotCache cache;
    tbb::parallel_for(0, 2000, [&](int i) {
        const auto& m = *models[std::size_t(i % 3)];
        cache.get(m, 0, ViewSet::Cube26, (i / 3) % 26, 1.0);
    });
    EXPECT_EQ(cache.counters().bakes, 78u);
    EXPECT_EQ(cache.counters().scenesBuilt, 3u);
}

/// A byte budget of three and a half face views of `cube` at sigma 1 (face views of a cube have
/// equal sizes): three fit, a fourth evicts one.
SnapshotCacheConfig budgetOfThreeFaceViews(const VoxelModel& cube) {
    SnapshotCache probe;
    const std::size_t one = probe.get(cube, 0, ViewSet::Cube26, 0, 1.0)->bytes();
    SnapshotCacheConfig cfg;
    cfg.budgetBytes = 3 * one + one / 2;
    return cfg;
}

// A budget of three holds three; the least recently used goes first, a touched one stays, and the
// bytes never exceed the budget.
TEST(SnapshotCache, LruEvictionKeepsTheBudgetAndDropsTheLeastRecentlyUsed) {
    const auto m = makeBox({8, 8, 8});
    const SnapshotCacheConfig cfg = budgetOfThreeFaceViews(*m);
    SnapshotCache cache(cfg);
    auto key = [&](int v) {
        return SnapshotKey{m->uid(), 0, m->version(), viewIdOf(ViewSet::Cube26, v), 1.0};
    };
    for (int v : {0, 1, 2}) cache.get(*m, 0, ViewSet::Cube26, v, 1.0);
    EXPECT_EQ(cache.counters().evictions, 0u);
    cache.get(*m, 0, ViewSet::Cube26, 0, 1.0); // touch 0: now 1 is the oldest
    const auto held = cache.get(*m, 0, ViewSet::Cube26, 3, 1.0);
    EXPECT_EQ(cache.counters().evictions, 1u);
    EXPECT_EQ(cache.find(key(1)), nullptr);
    EXPECT_NE(cache.find(key(0)), nullptr);
    EXPECT_NE(cache.find(key(2)), nullptr);
    EXPECT_NE(cache.find(key(3)), nullptr);
    for (int v = 0; v < 6; ++v) {
        cache.get(*m, 0, ViewSet::Cube26, v, 1.0);
        EXPECT_LE(cache.counters().bytes, cfg.budgetBytes);
    }
    EXPECT_EQ(cache.counters().snapshots, 3u);
    // An evicted snapshot stays valid for whoever holds it.
    cache.setBudget(0);
    EXPECT_EQ(cache.counters().bytes, 0u);
    EXPECT_EQ(held->view, viewIdOf(ViewSet::Cube26, 3));
    EXPECT_GT(held->solidCount(), 0u);
}

// A frame bakes views of many (model, animation frame)s in turn; each needs its Embree scene.
// Twelve models asked for one view each, round after round: under the default byte budget each
// scene is built once; under a budget of two and a half scenes they are rebuilt (least recently
// used goes first), and the bytes held never pass the budget.
TEST(SnapshotCache, EmbreeScenesAreKeptWithinTheirByteBudget) {
    std::vector<std::shared_ptr<VoxelModel>> models;
    for (int i = 0; i < 12; ++i) models.push_back(makeBox({6 + i % 3, 7, 8 + i / 3}));
    auto rounds = [&](SnapshotCache& cache) {
        for (int round = 0; round < 3; ++round)
            for (const auto& m : models) cache.get(*m, 0, ViewSet::Cube26, round, 1.0);
    };
    SnapshotCache roomy;
    rounds(roomy);
    EXPECT_EQ(roomy.counters().bakes, 36u);
    EXPECT_EQ(roomy.counters().scenesBuilt, 12u);

    SnapshotCacheConfig cfg;
    cfg.sceneBudgetBytes = 5 * std::size_t(roomy.counters().sceneBytes) / 24;
    SnapshotCache tight(cfg);
    rounds(tight);
    EXPECT_EQ(tight.counters().bakes, 36u);
    EXPECT_EQ(tight.counters().scenesBuilt, 36u); // round robin over 12 with room for 2
    EXPECT_LE(tight.counters().sceneBytes, cfg.sceneBudgetBytes);
    EXPECT_GT(tight.counters().sceneBytes, 0u);
}

// An edit bumps the model version: the next request misses and bakes the edited model.
TEST(SnapshotCache, VersionBumpMissesAndBakesTheEditedModel) {
    const auto m = makeBox({6, 6, 6});
    SnapshotCache cache;
    const auto before = cache.get(*m, 0, ViewSet::Cube26, 4, 1.0); // +Z view, looking down
    const std::uint64_t v0 = m->version();
    ASSERT_TRUE(m->clearBox(0, {{0, 0, 3}, {6, 6, 6}})); // remove the top half
    EXPECT_GT(m->version(), v0);
    const auto after = cache.get(*m, 0, ViewSet::Cube26, 4, 1.0);
    const auto c = cache.counters();
    EXPECT_EQ(c.misses, 2u);
    EXPECT_EQ(c.bakes, 2u);
    EXPECT_EQ(c.scenesBuilt, 2u); // a new (model, frame, version) scene
    EXPECT_NE(before, after);
    // The same silhouette from above, but the depth moved and the edit is visible: compare with
    // a scalar bake of the edited grid.
    const Snapshot expect = bakeSnapshotScalar(m->frame(0), ViewSet::Cube26, 4, 1.0);
    EXPECT_EQ(after->cells, expect.cells);
    ASSERT_TRUE(m->setVoxel(0, {0, 0, 2}, 5)); // recolour a visible top voxel
    const auto recoloured = cache.get(*m, 0, ViewSet::Cube26, 4, 1.0);
    EXPECT_NE(recoloured->cells, after->cells);
}

TEST(SnapshotCache, KeysSeparateSigmaDirectionAndFrame) {
    const auto m = test::arrowThenSphere();
    const VoxelGrid &a = m->frame(0), &b = m->frame(1);
    SnapshotCache cache;
    const auto s1 = cache.get(*m, 0, ViewSet::Cube26, 2, 1.0);
    const auto s2 = cache.get(*m, 0, ViewSet::Cube26, 2, 2.0);
    const auto s3 = cache.get(*m, 0, ViewSet::Cube98, 26, 1.0); // (-2,-2,-1): not in Cube26
    const auto s4 = cache.get(*m, 1, ViewSet::Cube26, 2, 1.0);
    EXPECT_EQ(cache.counters().bakes, 4u);
    EXPECT_EQ(cache.counters().scenesBuilt, 2u); // per (model, frame, version)
    EXPECT_EQ(s2->lattice.sigma, 2.0);
    EXPECT_EQ(s3->view, viewIdOf(viewLatticePoints(ViewSet::Cube98)[26]));
    EXPECT_EQ(s4->lattice.dims, b.dims());
    EXPECT_EQ(s1->cells, bakeSnapshotScalar(a, ViewSet::Cube26, 2, 1.0).cells);
}

// A snapshot is a view of a direction, not of a set: view 2 (+Y) of every set is the lattice
// direction (0, 1, 0), and the 98-set's (2, 2, 0) is the 26-set's edge view (1, 1, 0).
TEST(SnapshotCache, OneSnapshotServesEverySetHoldingItsDirection) {
    const auto m = test::arrowThenSphere();
    SnapshotCache cache;
    const auto y26 = cache.get(*m, 0, ViewSet::Cube26, 2, 1.0);
    EXPECT_EQ(cache.get(*m, 0, ViewSet::Cube98, 2, 1.0), y26);
    EXPECT_EQ(cache.get(*m, 0, ViewSet::Cube218, 2, 1.0), y26);
    const auto& p98 = viewLatticePoints(ViewSet::Cube98);
    const auto edge = std::find(p98.begin(), p98.end(), glm::ivec3(2, 2, 0));
    ASSERT_NE(edge, p98.end());
    const int edgeIndex = int(edge - p98.begin());
    EXPECT_EQ(viewIdOf(ViewSet::Cube98, edgeIndex).lattice, glm::ivec3(1, 1, 0));
    EXPECT_EQ(cache.get(*m, 0, ViewSet::Cube98, edgeIndex, 1.0),
              cache.get(*m, 0, viewIdOf(glm::ivec3(1, 1, 0)), 1.0));
    EXPECT_EQ(cache.counters().bakes, 2u);
    // The shared direction is the same double vector whichever set names it.
    EXPECT_EQ(viewDirections(ViewSet::Cube98)[std::size_t(edgeIndex)],
              viewDirections(ViewSet::Cube26)[std::size_t(
                  std::find(viewLatticePoints(ViewSet::Cube26).begin(),
                            viewLatticePoints(ViewSet::Cube26).end(), glm::ivec3(1, 1, 0)) -
                  viewLatticePoints(ViewSet::Cube26).begin())]);
}

// A frame's far batch holds each distinct snapshot its requests show once, in the order the
// requests first show them, and each drawn instance points at its own: two models at all 98
// views (the batch's table of snapshots grows several times), each asked for three times in a
// shuffled order, and a culled sprite's requests, which draw nothing.
TEST(FarBatch, EachDistinctSnapshotOnceInTheOrderFirstShown) {
    Scene s = test::hundredEntityWall(makeSphere(4), -20.0);
    s.models.push_back(test::arrowThenSphere());
    s.entities[1].model = 1;
    s.entities[1].frame = 1;
    s.entities[2].position.z = 20.0; // behind the camera
    const CameraFrame cam = makeCameraFrame(s.camera);
    const std::vector<SpriteSetup> sprites = setupSprites(s, cam, 0.0);
    ASSERT_TRUE(sprites[0].visible() && sprites[1].visible());
    ASSERT_FALSE(sprites[2].visible());
    std::vector<FarRequest> requests;
    for (int round = 0; round < 3; ++round)
        for (int v = 0; v < 98; ++v)
            for (int e : {0, 1, 2}) requests.push_back({&sprites[e], viewIdOf(ViewSet::Cube98, v)});
    SplitMix64 rng{47};
    for (std::size_t k = requests.size() - 1; k > 0; --k)
        std::swap(requests[k], requests[std::size_t(rng.next() % (k + 1))]);

    SnapshotCache cache;
    const FarBatch batch = prepareFarBatch(s.models, requests, cache, ViewSet::Cube98);
    ASSERT_EQ(batch.snapshots.size(), 2u * 98u);
    ASSERT_EQ(batch.instances.size(), 2u * 3u * 98u);
    std::map<std::pair<const SpriteSetup*, glm::ivec3>, std::uint32_t,
             bool (*)(const std::pair<const SpriteSetup*, glm::ivec3>&,
                      const std::pair<const SpriteSetup*, glm::ivec3>&)>
        firstShown([](const auto& a, const auto& b) {
            return std::tie(a.first, a.second.x, a.second.y, a.second.z) <
                   std::tie(b.first, b.second.x, b.second.y, b.second.z);
        });
    std::size_t drawn = 0;
    for (const FarRequest& r : requests) {
        if (!r.sprite->visible()) continue;
        const FarInstance& f = batch.instances.at(drawn++);
        ASSERT_EQ(f.sprite, r.sprite);
        const auto [it, added] =
            firstShown.try_emplace({r.sprite, r.view->lattice}, std::uint32_t(firstShown.size()));
        ASSERT_EQ(f.snapshot, it->second) << "request " << drawn - 1;
        const SpriteSetup& sp = *r.sprite;
        EXPECT_EQ(batch.snapshots[f.snapshot].owner.get(),
                  cache
                      .get(*s.models[std::size_t(sp.model)], sp.frame, *r.view,
                           sp.lattice.sigma * cache.snapshotScale())
                      .get());
    }
    EXPECT_EQ(firstShown.size(), batch.snapshots.size());
}

// A renderer keeps one batch and its scratch from frame to frame: the batch of each frame is the
// one a single core walking its requests gives (written out below), however many requests (over
// several of the scratch's chunks of 4,096), however many threads, and whatever the frames before
// left in the scratch (frames of 20,000, 3,000 and 30,000 requests, the table grown in between).
// Each request shows one of three model frames in one of 218 views, given or the set's nearest,
// and a tenth of them a culled sprite.
TEST(FarBatch, KeptScratchGivesTheBatchOneCoreWalkingTheRequestsGives) {
    Scene s = test::hundredEntityWall(makeSphere(4), -20.0);
    s.models.push_back(test::arrowThenSphere());
    for (int e = 0; e < 100; ++e) {
        s.entities[std::size_t(e)].model = e % 3 == 0 ? 0 : 1;
        s.entities[std::size_t(e)].frame = e % 3 == 2 ? 1 : 0;
        if (e % 10 == 9) s.entities[std::size_t(e)].position.z = 20.0; // behind the camera
    }
    const CameraFrame cam = makeCameraFrame(s.camera);
    const std::vector<SpriteSetup> sprites = setupSprites(s, cam, 0.0);
    ASSERT_FALSE(sprites[9].visible());
    ASSERT_TRUE(sprites[0].visible() && sprites[1].visible() && sprites[2].visible());
    const ViewSet set = ViewSet::Cube218;
    SnapshotCache cache;
    FarBatch batch;
    FarBatchScratch scratch;
    SplitMix64 rng{2026};
    int frame = 0;
    for (const std::size_t count : {20000u, 3000u, 30000u, 20000u}) {
        std::vector<FarRequest> requests(count);
        for (FarRequest& r : requests) {
            r.sprite = &sprites[std::size_t(rng.next() % sprites.size())];
            const int v = int(rng.next() % 219); // 218: the nearest view of the set
            if (v < 218) r.view = viewIdOf(set, v);
        }
        tbb::task_arena arena(frame % 2 == 0 ? 4 : 1);
        arena.execute([&] { prepareFarBatch(s.models, requests, cache, set, batch, scratch); });
        // One core's walk: the distinct (model, frame, view, sigma) in the order first shown.
        using Key = std::tuple<int, int, int, int, int, double>;
        std::map<Key, std::uint32_t> firstShown;
        std::size_t drawn = 0;
        for (std::size_t k = 0; k < requests.size(); ++k) {
            const SpriteSetup& sp = *requests[k].sprite;
            if (!sp.visible()) continue;
            const ViewId view =
                requests[k].view ? *requests[k].view : viewIdOf(set, chooseFarView(sp, set));
            const double sigma = sp.lattice.sigma * cache.snapshotScale();
            const auto [it, added] = firstShown.try_emplace(
                Key{sp.model, sp.frame, view.lattice.x, view.lattice.y, view.lattice.z, sigma},
                std::uint32_t(firstShown.size()));
            ASSERT_LT(drawn, batch.instances.size()) << "frame " << frame;
            const FarInstance& f = batch.instances[drawn++];
            ASSERT_EQ(f.sprite, &sp) << "frame " << frame << ", request " << k;
            ASSERT_EQ(f.snapshot, it->second) << "frame " << frame << ", request " << k;
            ASSERT_EQ(f.palette, &s.models[std::size_t(sp.model)]->palette());
            const std::shared_ptr<const Snapshot> snap =
                cache.get(*s.models[std::size_t(sp.model)], sp.frame, view, sigma);
            ASSERT_EQ(batch.snapshots.at(f.snapshot).owner.get(), snap.get());
            if (added) {
                const FarSnapshotCells& cells = batch.snapshots[f.snapshot];
                EXPECT_EQ(cells.cells, reinterpret_cast<const std::uint8_t*>(snap->cells.data()));
                EXPECT_EQ(cells.cellRange, snap->lattice.cellRange);
                EXPECT_NE(cells.lineage, 0u);
            }
            const SnapshotCellMap m = snapshotCellMap(sp.lattice, snap->lattice);
            ASSERT_EQ(std::tie(f.u0, f.ui, f.uj, f.v0, f.vi, f.vj),
                      std::tie(m.u0, m.ui, m.uj, m.v0, m.vi, m.vj));
        }
        EXPECT_EQ(batch.instances.size(), drawn) << "frame " << frame;
        EXPECT_EQ(batch.snapshots.size(), firstShown.size()) << "frame " << frame;
        EXPECT_GT(firstShown.size(), 400u);
        EXPECT_GT(drawn, count * 8 / 10);
        ++frame;
    }
}

// getAll gives each ask what get() gives it, and makes the cached ones the most recent in the
// order asked, before the missing ones are baked: a budget of three snapshots holding views 0, 1
// and 2 (2 the most recent), asked for 1, 0, 3 and 1 again, keeps 1, 0 and 3 and drops 2.
TEST(SnapshotCache, GetAllGivesWhatGetGivesAndTouchesTheCachedInTheOrderAsked) {
    const auto m = makeBox({8, 8, 8});
    SnapshotCache cache(budgetOfThreeFaceViews(*m));
    const auto view = [](int v) { return viewIdOf(ViewSet::Cube26, v); };
    const auto key = [&](int v) { return SnapshotKey{m->uid(), 0, m->version(), view(v), 1.0}; };
    for (int v : {0, 1, 2}) cache.get(*m, 0, view(v), 1.0);
    const SnapshotCacheCounters before = cache.counters();
    const std::vector<SnapshotCache::Ask> asks{{m.get(), 0, view(1), 1.0},
                                               {m.get(), 0, view(0), 1.0},
                                               {m.get(), 0, view(3), 1.0},
                                               {m.get(), 0, view(1), 1.0}};
    std::vector<std::shared_ptr<const Snapshot>> out(asks.size());
    cache.getAll(asks, out);
    const SnapshotCacheCounters after = cache.counters();
    EXPECT_EQ(after.bakes - before.bakes, 1u);
    EXPECT_EQ(after.hits - before.hits, 3u);
    EXPECT_EQ(after.misses - before.misses, 1u);
    EXPECT_EQ(after.evictions - before.evictions, 1u);
    EXPECT_EQ(cache.find(key(2)), nullptr);
    for (int v : {0, 1, 3}) EXPECT_NE(cache.find(key(v)), nullptr) << "view " << v;
    EXPECT_EQ(out[0], cache.find(key(1)));
    EXPECT_EQ(out[1], cache.find(key(0)));
    EXPECT_EQ(out[2], cache.find(key(3)));
    EXPECT_EQ(out[3], out[0]);
    EXPECT_EQ(out[2]->view, view(3));
    // Each ask as get() answers it, from a cache that never saw this one's.
    SnapshotCache fresh;
    for (std::size_t i = 0; i < asks.size(); ++i)
        EXPECT_EQ(test::firstSnapshotDifference(*out[i], *fresh.get(*m, 0, asks[i].view, 1.0)), "");
    std::vector<std::shared_ptr<const Snapshot>> short_(1);
    EXPECT_THROW(cache.getAll(asks, short_), std::invalid_argument);
}

} // namespace
} // namespace voxtier
