// Planning what changed (FramePlanner::plan with SpriteStore::reposed, as FrameRenderer plans):
// along a sequence of frames in which a few entities move, animated ones step to other frames,
// the camera now and then moves and cross-fades run, a planner told what changed gives the plan
// and the figures of a planner that plans every entity every frame, while planning only the
// moved and fading entities on a still camera: an animation step alone changes a sprite's frame
// and skip rule, which no plan reads. A frame of another mode or config, or one the selector did
// not see, makes the next frame plan everything again.
#include "core/scene_loader.hpp"
#include "core/sprite_store.hpp"
#include "lod/frame_planner.hpp"
#include "source_tree.hpp"

#include <gtest/gtest.h>

#include <random>
#include <vector>

namespace voxtier {
namespace {

/// The bench crowd (800 entities, 40 animated) with hysteresis on both switches.
Scene crowd(SelectorMetric metric) {
    Scene s = loadScene(test::sourcePath("scenes/bench/vox_crowd.json"));
    s.selector = defaultSelectorFor(metric);
    s.selector.crossfadeFrames = 3;
    s.selector.viewHysteresisDeg = 4.0;
    return s;
}

struct Step {
    PlanMode mode = PlanMode::Hybrid;
    bool moveCamera = false;
};

/// Runs `steps` through two planners on the same sprites: `told` is given the store's changes and
/// its selection inputs (as FrameRenderer plans), `whole` plans every entity from the sprites
/// alone. Returns the entities `told` planned, frame by frame; `steppedOnly`
/// (optional) gets, frame by frame, the sprites that changed only by an animation step.
std::vector<int> compare(Scene s, const std::vector<Step>& steps,
                         std::vector<int>* steppedOnly = nullptr) {
    SpriteStore store;
    FramePlanner told(s.selector), whole(s.selector);
    std::mt19937 rng(7);
    std::uniform_real_distribution<double> step(-12.0, 12.0);
    std::uniform_int_distribution<std::size_t> pick(0, s.entities.size() - 1);
    double cameraTime = 0.0;
    std::vector<int> planned;
    // The last two frames' plans stay held, as frames in flight hold theirs: a plan written while
    // they are comes in another array, which must end up the same.
    std::vector<SharedVector<EntityPlan>> inFlight;
    for (std::size_t f = 0; f < steps.size(); ++f) {
        // A few entities move, far enough to cross near_at or far_at now and then.
        for (int k = 0; k < 20; ++k) s.entities[pick(rng)].position.z += step(rng);
        if (steps[f].moveCamera) cameraTime += 0.4;
        const double t = s.timeOfFrame(int(f)); // animated entities step on
        store.update(s, makeCameraFrame(s.cameraAt(cameraTime)), t);
        PlanSettings settings;
        settings.mode = steps[f].mode;
        // Under the error budget: every snapshot cached but those of views whose x is a multiple
        // of 3.
        settings.inMemory = [](const SpriteSetup&, ViewId v) { return v.lattice.x % 3 != 0; };
        PlanStats a, b;
        const SharedVector<EntityPlan> pa =
            told.plan(store.sprites(), store.visibleIds(), s.selector, settings, a, store.reposed(),
                      store.selectionInputs());
        int stepped = 0;
        for (std::size_t i = 0; i < s.entities.size(); ++i)
            stepped += store.changed()[i] && !store.reposed()[i];
        if (steppedOnly) steppedOnly->push_back(stepped);
        const SharedVector<EntityPlan> pb =
            whole.plan(store.sprites(), store.visibleIds(), s.selector, settings, b);
        EXPECT_EQ(b.planned, steps[f].mode == PlanMode::AllNear ? 0 : int(s.entities.size()));
        for (std::size_t i = 0; i < pb.size(); ++i)
            EXPECT_TRUE(pa[i] == pb[i]) << "frame " << f << ", entity " << i;
        EXPECT_EQ(a.switchesToFar, b.switchesToFar) << "frame " << f;
        EXPECT_EQ(a.switchesToNear, b.switchesToNear) << "frame " << f;
        EXPECT_EQ(a.viewChanges, b.viewChanges) << "frame " << f;
        EXPECT_EQ(a.fading, b.fading) << "frame " << f;
        EXPECT_EQ(a.worstVpx, b.worstVpx) << "frame " << f;
        EXPECT_EQ(a.farOverOneVpx, b.farOverOneVpx) << "frame " << f;
        planned.push_back(a.planned);
        inFlight.push_back(pa);
        if (inFlight.size() > 2) inFlight.erase(inFlight.begin());
    }
    return planned;
}

std::vector<Step> hybridSteps(int frames) {
    std::vector<Step> steps(static_cast<std::size_t>(frames));
    for (int f = 0; f < frames; f += 12) steps[std::size_t(f)].moveCamera = true;
    return steps;
}

TEST(IncrementalPlan, HybridDistanceFramesEqualWholePlansAndPlanOnlyWhatChanged) {
    std::vector<int> steppedOnly;
    const std::vector<int> planned =
        compare(crowd(SelectorMetric::Distance), hybridSteps(48), &steppedOnly);
    EXPECT_EQ(planned[0], 800) << "the first frame plans everything";
    EXPECT_EQ(planned[12], 800) << "a moved camera changes every sprite";
    int fewest = 800, stepped = 0;
    for (std::size_t f = 1; f < 12; ++f) fewest = std::min(fewest, planned[f]);
    for (std::size_t f = 1; f < planned.size(); ++f) stepped += f % 12 ? steppedOnly[f] : 0;
    EXPECT_LT(fewest, 100) << "a still camera plans the moved and fading entities";
    EXPECT_GT(stepped, 0) << "animated entities stepped on still-camera frames, unplanned";
}

TEST(IncrementalPlan, ErrorPxViewsAndAllFarFramesEqualWholePlans) {
    const std::vector<int> planned = compare(crowd(SelectorMetric::ErrorPx), hybridSteps(36));
    EXPECT_LT(planned[5], 800);
    std::vector<Step> far = hybridSteps(24);
    for (Step& st : far) st.mode = PlanMode::AllFar;
    EXPECT_LT(compare(crowd(SelectorMetric::Distance), far)[5], 800);
}

// The error budget plans every entity every frame (its views share a bake bound), from the
// store's selection inputs where given: the same plans and figures as from the sprites.
TEST(IncrementalPlan, ErrorBudgetFramesFromTheStoresSelectionInputsEqualWholePlans) {
    Scene s = crowd(SelectorMetric::ErrorBudget);
    // About 470-500 of the 800 entities far, from views of the first two ladder levels.
    s.selector.budgetVpx = 0.5;
    s.selector.ladderCap = 2;
    const std::vector<int> planned = compare(s, hybridSteps(24));
    EXPECT_EQ(planned[5], 800);
}

TEST(IncrementalPlan, AnotherModeOrANearFrameMakesTheNextFramePlanEverything) {
    std::vector<Step> steps = hybridSteps(20);
    steps[6].mode = PlanMode::AllNear; // the selector does not see it
    steps[12].mode = PlanMode::AllFar;
    const std::vector<int> planned = compare(crowd(SelectorMetric::Distance), steps);
    EXPECT_LT(planned[5], 800);
    EXPECT_EQ(planned[6], 0);
    EXPECT_EQ(planned[7], 800) << "after a frame the selector did not see";
    EXPECT_EQ(planned[12], 800) << "all-far after hybrid";
    EXPECT_EQ(planned[13], 800) << "hybrid after all-far";
    EXPECT_LT(planned[14], 800);
}

} // namespace
} // namespace voxtier
