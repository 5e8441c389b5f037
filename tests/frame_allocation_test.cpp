// Set-up and selection allocate nothing of O(entities) per frame (issue 35): the sprite store and
// the frame planner keep their arrays, so once a scene's entities are known a moving camera's
// frame allocates at most a few small things, whatever the entity count. Counted here by every
// operator new of this test program, on every thread, across SpriteStore::update and
// FramePlanner::plan as FrameRenderer calls them, with the last two frames' results held as
// frames in flight hold them.
#include "core/sprite_store.hpp"
#include "crowd_scenes.hpp"
#include "lod/frame_planner.hpp"

#include <gtest/gtest.h>

#include <atomic>
#include <cstdio>
#include <cstdlib>
#include <deque>
#include <new>

namespace {
std::atomic<bool> counting{false};
std::atomic<std::size_t> allocatedBytes{0}, allocations{0};
} // namespace

void* operator new(std::size_t bytes) {
    if (counting.load(std::memory_order_relaxed)) {
        allocatedBytes += bytes;
        ++allocations;
    }
    if (void* p = std::malloc(bytes ? bytes : 1)) return p;
    throw std::bad_alloc();
}
// Not inlined: inlined into a caller, GCC sees free() meet a pointer from operator new and warns
// of a mismatched pair (-Wmismatched-new-delete), which a replacement of both is not.
[[gnu::noinline]] void operator delete(void* p) noexcept {
    std::free(p);
}
[[gnu::noinline]] void operator delete(void* p, std::size_t) noexcept {
    std::free(p);
}

namespace voxtier {
namespace {

struct Allocated {
    std::size_t bytes = 0, count = 0; ///< the most of any frame after the first ones
};

/// Frames 0..frames-1 of the army's camera path; what frames `warmUp` on allocated at most.
Allocated allocatedPerFrame(int entities, SelectorMetric metric, PlanMode mode) {
    Scene s = test::tankArmy(entities, 320, 180);
    if (metric == SelectorMetric::ErrorBudget) {
        s.selector.metric = metric;
        s.selector.budgetVpx = 1.0;
    }
    SpriteStore store;
    FramePlanner planner(s.selector);
    PlanSettings settings;
    settings.mode = mode;
    // Under the error budget every view is cached (no bake waits): the frame a camera move
    // brings, with what a warm cache answers.
    settings.inMemory = [](const SpriteSetup&, ViewId) { return true; };
    std::deque<std::pair<SharedVector<SpriteSetup>, SharedVector<EntityPlan>>> inFlight;
    std::deque<SharedVector<std::uint32_t>> visibleInFlight;
    Allocated most;
    const int frames = 14, warmUp = 4;
    for (int f = 0; f < frames; ++f) {
        const double t = s.timeOfFrame(f);
        const CameraFrame camera = makeCameraFrame(s.cameraAt(t));
        allocatedBytes = 0;
        allocations = 0;
        counting = true;
        store.update(s, camera, t);
        SharedVector<SpriteSetup> sprites = store.shareSprites();
        SharedVector<std::uint32_t> visible = store.shareVisibleIds();
        PlanStats stats;
        SharedVector<EntityPlan> plan = planner.plan(store.sprites(), store.visibleIds(),
                                                     s.selector, settings, stats, store.reposed());
        counting = false;
        // Two frames in flight, as a path render holds them.
        inFlight.emplace_back(std::move(sprites), std::move(plan));
        visibleInFlight.push_back(std::move(visible));
        if (inFlight.size() > 2) inFlight.pop_front(), visibleInFlight.pop_front();
        if (f >= warmUp) {
            most.bytes = std::max<std::size_t>(most.bytes, allocatedBytes);
            most.count = std::max<std::size_t>(most.count, allocations);
        }
    }
    return most;
}

TEST(FrameAllocation, SetUpAndSelectionOfAMovingCameraAllocateNothingThatGrowsWithTheEntities) {
    const struct {
        SelectorMetric metric;
        PlanMode mode;
        const char* what;
    } cases[] = {{SelectorMetric::ErrorPx, PlanMode::Hybrid, "hybrid, error_px"},
                 {SelectorMetric::ErrorPx, PlanMode::AllFar, "all far"},
                 {SelectorMetric::ErrorPx, PlanMode::AllNear, "all near"},
                 {SelectorMetric::ErrorBudget, PlanMode::Hybrid, "hybrid, error budget"}};
    for (const auto& c : cases) {
        const Allocated small = allocatedPerFrame(2000, c.metric, c.mode);
        const Allocated large = allocatedPerFrame(20000, c.metric, c.mode);
        std::printf("%s: at most %zu bytes in %zu allocations a frame at 2,000 entities, %zu in "
                    "%zu at 20,000\n",
                    c.what, small.bytes, small.count, large.bytes, large.count);
        // 20,000 entities' arrays are megabytes; a few kilobytes of bookkeeping are not.
        EXPECT_LE(large.bytes, small.bytes + 16384) << c.what;
        EXPECT_LE(large.count, small.count + 16) << c.what;
    }
}

} // namespace
} // namespace voxtier
