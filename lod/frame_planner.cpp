#include "lod/frame_planner.hpp"

#include "core/stopwatch.hpp"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/parallel_reduce.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <functional>
#include <utility>

namespace voxtier {

SharedVector<EntityPlan> FramePlanner::plan(std::span<const SpriteSetup> sprites,
                                            std::span<const std::uint32_t> visible,
                                            const SelectorConfig& config,
                                            const PlanSettings& settings, PlanStats& st,
                                            std::span<const std::uint8_t> changed,
                                            std::span<const SpriteSelectionInputs> selection) {
    const std::size_t n = sprites.size();
    if (settings.mode == PlanMode::AllNear) {
        plan_.fresh().assign(n, EntityPlan{});
        st.planned = 0;
        chained_ = false; // the selector does not see this frame: the next one starts afresh
        return plan_.share();
    }
    const ViewSet set = viewSetFromSize(config.viewSetSize);
    const auto& views = viewDirections(set);
    const bool hybrid = settings.mode == PlanMode::Hybrid;
    const bool budget = config.metric == SelectorMetric::ErrorBudget && hybrid;
    if (selector_.size() == 0) budgetViews_.reset(); // a restarted selector restarts its views
    // Only the entities whose sprite changed, or that are inside a cross-fade, where the frame
    // before was planned here the same way: every other entity's inputs, and so its selector
    // state, tier and view, are last frame's (TierSelector::settled). Not under the error
    // budget, whose views share a bake bound and depend on what the cache holds.
    const bool incremental = !budget && chained_ && changed.size() == n && selector_.size() == n &&
                             plan_.read().size() == n && settings.mode == lastMode_ &&
                             config == lastConfig_;
    chained_ = true, lastMode_ = settings.mode, lastConfig_ = config;
    predicted_.resize(n);
    work_.clear();
    if (incremental)
        for (std::size_t i = 0; i < n; ++i)
            if (changed[i] || !selector_.settled(i)) work_.push_back(std::uint32_t(i));
    st.planned = int(incremental ? work_.size() : n);
    // A frame that plans every entity (a moved camera's too) reads nothing of the last plan and
    // writes every entity's (tierOf, below): not copied, were a frame in flight still holding it,
    // nor cleared first.
    std::vector<EntityPlan>& plan =
        incremental && work_.size() < n ? plan_.writable() : plan_.overwritable(n);

    // Each sprite's selection inputs: the caller's (a store keeps them, 96 bytes an entity read
    // in order), or derived here first from the sprites.
    const bool given = selection.size() == n;
    if (!given) ownSelection_.resize(n);
    const std::span<const SpriteSelectionInputs> in = given ? selection : ownSelection_;
    // The selector sees distance, projected radius and the angle to the nearest snapshot view
    // (or, under the error budget, the best prediction over the budget); `nearest` gets that
    // view's index (error_px).
    const auto selectorInput = [&](std::size_t i, int& nearest) {
        if (!given) ownSelection_[i] = selectionInputs(sprites[i]);
        const SpriteSelectionInputs& s = in[i];
        SelectorInput x{s.distance, s.radiusPx, 0.0, 0.0};
        if (!s.visible) return x;
        if (budget) { // the error budget's metric; the view angle serves only error_px
            x.budgetShare = bestBudgetUnits(s, config) / config.budgetVpx;
            return x;
        }
        nearest = nearestView(set, s.towardViewer);
        const glm::dvec3 w = views[std::size_t(nearest)];
        x.viewCos = std::clamp(glm::dot(w, s.towardViewer), -1.0, 1.0);
        return x;
    };
    // f(entity, sum) for each entity this frame plans (the work list, or all), in parallel, each
    // task summing into its own copy of `identity`, joined by `join`. At most 128 entities a
    // task: a few thousand still spread over 16 cores.
    const auto reduceEach = [&](auto identity, auto&& f, auto&& join) {
        const auto over = [&](auto&& entityAt, std::size_t count) {
            return tbb::parallel_reduce(
                tbb::blocked_range<std::size_t>(0, count, 128), identity,
                [&](const auto& r, auto sum) {
                    for (std::size_t k = r.begin(); k != r.end(); ++k) f(entityAt(k), sum);
                    return sum;
                },
                join);
        };
        return incremental
                   ? over([&](std::size_t k) { return std::size_t(work_[k]); }, work_.size())
                   : over([](std::size_t i) { return i; }, n);
    };
    const auto forEach = [&](auto&& f) {
        reduceEach(
            0, [&](std::size_t i, int) { f(i); }, [](int, int) { return 0; });
    };
    auto step = std::chrono::steady_clock::now();
    // The cross-fades counted and the worst prediction found (one core counted 100,000 plans,
    // which more cores do not shrink).
    struct FadingWorst {
        int fading = 0;
        double worst = 0.0;
        int overOne = 0;
        void add(float fade, double predicted) {
            fading += fade > 0.0f;
            worst = std::max(worst, predicted);
            overOne += predicted > 1.0;
        }
        static FadingWorst sum(FadingWorst a, const FadingWorst& b) {
            return {a.fading + b.fading, std::max(a.worst, b.worst), a.overOne + b.overOne};
        }
    };
    // error_px: each entity's inputs, hysteresis step, tier, far view and prediction in one pass
    // over the entities (below). The error budget's views need every entity's tier first.
    SelectorStats ss;
    FadingWorst counts; // the frame's fades and worst prediction (error_px: its pass's)
    if (budget) {
        inputs_.resize(n);
        forEach([&](std::size_t i) {
            int unused = 0;
            inputs_[i] = selectorInput(i, unused);
        });
        st.ms.inputs = lapMs(step);
        ss = selector_.update(inputs_);
    }
    budgetViews_.beginFrame(n, config.maxBakesPerFrame);
    if (budget) st.ms.tiers = lapMs(step);
    const auto tierOf = [&](std::size_t i) {
        EntityPlan& p = plan[i];
        p = EntityPlan{};
        p.tier = settings.mode == PlanMode::AllFar ? Tier::Far : selector_.tier(i);
        if (hybrid) {
            float share = 0.0f;
            Tier from = p.tier;
            if (selector_.fading(i, &share, &from)) p.fade = share, p.fadeFrom = from;
        }
    };
    // Each far-drawn visible entity's predicted displacement, kept per entity so that a frame
    // that plans a few entities updates only theirs; the frame's worst is over all of them.
    const auto predict = [&](std::size_t i) {
        const EntityPlan& p = plan[i];
        // The plan first: a far view is only ever given to a visible sprite, and the sprites
        // drawn near (most of a hybrid frame) are then not read again.
        predicted_[i] =
            p.drawsFar() && p.view && in[i].visible ? predictedBudgetUnits(in[i], *p.view) : 0.0;
    };
    if (budget && holdFarTier(in, settings, tierOf, forEach, plan, st)) {
        // Held near: no view chosen, nothing baked, nothing drawn far, nothing predicted.
        st.ms.costBound = lapMs(step);
        std::fill(predicted_.begin(), predicted_.end(), 0.0);
    } else if (budget) {
        // The budget's views share the frame's bake bound, given out in entity order; what
        // each far entity's choice reads of no other entity (its tier, its levels' views and
        // predictions, the cache's answers) is found first, in parallel. An entity whose current
        // view is within the budget and cached keeps it there too (most far entities, most
        // frames): only the others are handed views in entity order. At 100,000 tanks a serial
        // pass over every entity read each one's sprite and cost 5-10 ms on two cores. Each
        // distinct question to the cache is asked of it once, and kept for the next frames while
        // the cache can tell what changed (SharedCacheAnswers).
        beginCacheAnswers(settings);
        PlanSettings asking = settings;
        asking.inMemory = [&](const SpriteSetup& s, ViewId v) {
            return cacheAnswers_.ask(s, v, settings.inMemory);
        };
        prepared_.resize(n);
        budgetStep_.resize(n);
        st.pausedNear = reduceEach(
            0,
            [&](std::size_t i, int& paused) {
                tierOf(i);
                EntityPlan& p = plan[i];
                if (!p.drawsFar() || !in[i].visible) {
                    budgetViews_.drop(i);
                    budgetStep_[i] = BudgetStep::Near;
                    return;
                }
                prepared_[i] = budgetViews_.prepare(i, sprites[i], in[i], config, asking.inMemory);
                if (budgetViews_.waitsOutThePause(i, prepared_[i])) {
                    // Near, unscanned, as choose() would have it, without the serial walk.
                    p = EntityPlan{};
                    budgetStep_[i] = BudgetStep::Near;
                    ++paused;
                    return;
                }
                if (!prepared_[i].settled()) {
                    budgetStep_[i] = BudgetStep::Choose;
                    return;
                }
                p.view = budgetViews_.keep(i);
                fadeBudgetView(i, sprites[i], in[i], config, asking, p);
                budgetStep_[i] = BudgetStep::Kept;
            },
            [](int a, int b) { return a + b; });
        st.ms.views = lapMs(step);
        // The bake bound goes out in entity order, one entity after another while bakes are left.
        // Once it is spent, the views baking this frame are fixed, and an entity's choice reads
        // nothing another's changes (each writes its own view and fade; the view changes are
        // counted atomically): the rest choose on every core. On the H200's 16 cores a moving
        // 100,000-tank army under a budget whose bakes the cost bound gives up had ~50,000
        // entities a frame waiting in this walk, 27-36 ms of selection (run 12).
        std::size_t next = 0;
        for (; next < n && budgetViews_.bakesLeft() > 0; ++next)
            if (budgetStep_[next] == BudgetStep::Choose)
                planBudgetView(next, sprites[next], in[next], config, asking, prepared_[next],
                               plan[next]);
        tbb::parallel_for(tbb::blocked_range<std::size_t>(next, n, 128), [&](const auto& r) {
            for (std::size_t i = r.begin(); i != r.end(); ++i)
                if (budgetStep_[i] == BudgetStep::Choose)
                    planBudgetView(i, sprites[i], in[i], config, asking, prepared_[i], plan[i]);
        });
        st.ms.choices = lapMs(step);
        st.cacheQuestions = int(cacheAnswers_.askedOfTheCache()); // no later step asks
        st.bakesGivenUp = keepAffordableBakes(sprites, in, visible, settings, plan);
        st.heldNear = settings.costAwareBakes ? budgetViews_.heldNearThisFrame() : 0;
        st.ms.costBound = lapMs(step);
        // After the bakes given up, which send their entities near (a kept one only with the
        // whole far tier held near: its view is cached, so no bake is asked for it). A kept
        // view's prediction is prepare()'s.
        forEach([&](std::size_t i) {
            if (budgetStep_[i] == BudgetStep::Kept && plan[i].drawsFar())
                predicted_[i] = prepared_[i].currentUnits;
            else
                predict(i);
        });
    } else {
        // Every entity on its own, in one parallel pass: its inputs, the selector's step, its
        // tier, its view and prediction, and (a whole frame) the counts. As separate passes they
        // wrote and read back the selector's inputs and the nearest views, read each entity's
        // selection inputs twice and waited for every thread three times more (100,000 moving
        // tanks on two cores: all far 3.1 -> 2.95 ms, the hybrid's 3.2-3.4 -> 2.3).
        const bool first = selector_.beginFrame(n, incremental);
        struct Pass {
            SelectorStats selector;
            FadingWorst counts;
        };
        const auto planOne = [&](std::size_t i, Pass& pass) {
            int nearest = 0;
            selector_.stepEntity(i, selectorInput(i, nearest), first, pass.selector);
            tierOf(i);
            predicted_[i] = 0.0;
            if (plan[i].drawsFar() && in[i].visible) {
                const int v = selector_.chooseView(i, in[i].towardViewer, views, nearest);
                plan[i].view = viewIdOf(set, v);
                // predict(i), the view's unit vector read from the set's table (viewDirection
                // of that id, to the bit) rather than normalised again.
                predicted_[i] = predictedBudgetUnits(in[i], views[std::size_t(v)]);
            }
            pass.counts.add(plan[i].fade, predicted_[i]);
        };
        const Pass pass = reduceEach(Pass{}, planOne, [](Pass a, const Pass& b) {
            return Pass{TierSelector::sum(a.selector, b.selector),
                        FadingWorst::sum(a.counts, b.counts)};
        });
        ss = pass.selector;
        counts = pass.counts;
        st.ms.inputs = lapMs(step);
    }
    st.switchesToFar = ss.switchesToFar;
    st.switchesToNear = ss.switchesToNear;
    st.viewChanges = selector_.viewChangesThisFrame() + budgetViews_.viewChangesThisFrame();
    // error_px counted them in its pass over the entities it planned: the fades are all of them
    // (every other entity is settled, so none of them fades), and on a whole frame the worst
    // too. The worst of a partial frame is over every entity (those outside the work list keep
    // last frame's predictions); the error budget counts everything here.
    if (budget || incremental) {
        const FadingWorst all = tbb::parallel_reduce(
            tbb::blocked_range<std::size_t>(0, n, 4096), FadingWorst{},
            [&](const auto& r, FadingWorst acc) {
                for (std::size_t i = r.begin(); i != r.end(); ++i)
                    acc.add(budget ? plan[i].fade : 0.0f, predicted_[i]);
                return acc;
            },
            FadingWorst::sum);
        if (budget) counts.fading = all.fading;
        counts.worst = all.worst;
        counts.overOne = all.overOne;
    }
    st.fading += counts.fading;
    st.worstVpx = counts.worst;
    st.farOverOneVpx = counts.overOne;
    st.ms.predictions = lapMs(step);
    return plan_.share();
}

SharedVector<EntityPlan> FramePlanner::plan(std::span<const SpriteSetup> sprites,
                                            const SelectorConfig& config,
                                            const PlanSettings& settings, PlanStats& stats) {
    std::vector<std::uint32_t> visible;
    for (std::size_t i = 0; i < sprites.size(); ++i)
        if (sprites[i].visible()) visible.push_back(std::uint32_t(i));
    return plan(sprites, visible, config, settings, stats);
}

void FramePlanner::beginCacheAnswers(const PlanSettings& settings) {
    if (!settings.inMemoryChangesSince) {
        answersThrough_.reset();
        return cacheAnswers_.begin();
    }
    answersChanged_.clear();
    const std::optional<std::uint64_t> since =
        settings.inMemoryEpoch == answersEpoch_ ? answersThrough_ : std::nullopt;
    const PlanSettings::InMemoryChanges changes =
        settings.inMemoryChangesSince(since, answersChanged_);
    if (since && changes.complete)
        cacheAnswers_.beginKeeping(answersChanged_);
    else
        cacheAnswers_.begin();
    answersThrough_ = changes.count;
    answersEpoch_ = settings.inMemoryEpoch;
}

void FramePlanner::planBudgetView(std::size_t entity, const SpriteSetup& sprite,
                                  const SpriteSelectionInputs& selection,
                                  const SelectorConfig& config, const PlanSettings& settings,
                                  const ErrorBudgetViews::Prepared& prepared, EntityPlan& p) {
    // In memory: preferred. On disk (--cache-dir): not a bake either, but never preferred, since
    // what a shared directory holds is up to other processes (ErrorBudgetViews::choose).
    p.view = budgetViews_.choose(entity, sprite, config, prepared, settings.withoutBake);
    // No view within the budget without passing this frame's bake bound: near this frame (the
    // selector keeps its far state, so the entity goes far as soon as a view can be had).
    if (!p.view) p = EntityPlan{};
    fadeBudgetView(entity, sprite, selection, config, settings, p);
}

void FramePlanner::fadeBudgetView(std::size_t entity, const SpriteSetup& sprite,
                                  const SpriteSelectionInputs& selection,
                                  const SelectorConfig& config, const PlanSettings& settings,
                                  EntityPlan& p) {
    // A view switch cross-fades like a tier switch (not on top of one).
    float share = 0.0f;
    ViewId from;
    if (p.view && p.tier == Tier::Far && p.fade <= 0.0f &&
        budgetViews_.viewFade(entity, sprite, selection, config, settings.inMemory, &share, &from))
        p.fade = share, p.fadeFrom = Tier::Far, p.fadeFromView = from;
}

template <class TierOf, class ForEach>
bool FramePlanner::holdFarTier(std::span<const SpriteSelectionInputs> in,
                               const PlanSettings& settings, const TierOf& tierOf,
                               const ForEach& forEach, std::vector<EntityPlan>& plan,
                               PlanStats& st) {
    const BakeCosts& costs = settings.bakeCosts ? *settings.bakeCosts : costs_.costs();
    if (!settings.costAwareBakes || !budgetViews_.farTierHeld() || !costs.known()) return false;
    // While the far tier is held near, no far sprite is drawn: the views it would be drawn from,
    // the bakes and the cache's answers would all be given up again (on the H200 the bench's
    // hybrids spent 0.8 ms of selection a frame on 2,000 tanks, the 100,000-tank one 9.4 ms).
    // So the tier is weighed first, as the selector draws it: every visible entity it puts far
    // (sumTierMs, as keepAffordableBakes weighs a frame with no bake). Let go, the frame plans as
    // every other (whose weighing of the entities given views then holds the tier again only
    // past the band's upper end).
    forEach(tierOf);
    const auto far = [&](std::size_t i) { return plan[i].drawsFar() && in[i].visible; };
    const TierMs tier = sumTierMs(plan.size(), [&](std::size_t i) {
        return far(i) ? TierMs{costs.farMs(in[i]), costs.nearMs(in[i]), 1} : TierMs{};
    });
    if (!budgetViews_.weighFarTier(tier.far, tier.near)) return false;
    // Near this frame, the views of the held entities kept (as keepAffordableBakes keeps a held
    // tier's cached ones); an entity the selector draws near starts its view afresh, as below.
    forEach([&](std::size_t i) {
        if (far(i))
            plan[i] = EntityPlan{};
        else
            budgetViews_.drop(i);
    });
    st.heldNear = tier.sprites;
    return true;
}

int FramePlanner::keepAffordableBakes(std::span<const SpriteSetup> sprites,
                                      std::span<const SpriteSelectionInputs> in,
                                      std::span<const std::uint32_t> visible,
                                      const PlanSettings& settings, std::vector<EntityPlan>& plan) {
    if (!settings.costAwareBakes) return 0;
    const std::size_t asked = budgetViews_.bakesAsked();
    // Filled on every core: one core wrote 100,000 entries and read each visible entity's plan,
    // work that more cores do not shrink (on two cores it measured within noise either way).
    drawnFrom_.resize(plan.size());
    mayUseABake_.resize(plan.size());
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, plan.size(), 4096), [&](const auto& r) {
        for (std::size_t i = r.begin(); i != r.end(); ++i) {
            drawnFrom_[i] = std::nullopt;
            // A kept view is cached: no bake (ErrorBudgetViews::keepAffordableBakes).
            mayUseABake_[i] = budgetStep_[i] == BudgetStep::Choose;
        }
    });
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, visible.size(), 4096), [&](const auto& r) {
        for (std::size_t k = r.begin(); k != r.end(); ++k)
            if (const std::uint32_t i = visible[k]; plan[i].drawsFar())
                drawnFrom_[i] = plan[i].view;
    });
    const BakeCosts& costs = settings.bakeCosts ? *settings.bakeCosts : costs_.costs();
    // Given up: near this frame, as under the bake bound (the selector keeps its far state).
    for (std::size_t i :
         budgetViews_.keepAffordableBakes(sprites, drawnFrom_, costs, mayUseABake_, in))
        plan[i] = EntityPlan{};
    return int(asked - budgetViews_.bakesAsked());
}

void CostModel::observe(std::span<const SpriteSetup> sprites,
                        std::span<const std::uint32_t> visible, std::span<const EntityPlan> plan,
                        const FrameCostSample& sample, NearRate rate,
                        const std::function<double()>& nearFixedMs) {
    costs_.nearRate = rate;
    // The sums over the visible sprites, only where a figure below reads them: an all-near or
    // all-far frame, or one not planned by the error budget, needs neither or one. At 100,000
    // sprites one core walking them all (a cache miss apiece) cost 5-7 ms of every frame on two
    // cores, outside every named part of it. In parallel, and deterministic: the same sums
    // whatever the threads, so that a plan depends on the frames' times alone.
    const bool wantNear = sample.planned && sample.nearMs > 0.0;
    // The far tier's per-frame cost: without its snapshot uploads, which a snapshot pays once
    // (as a model pays its voxel uploads once, below). Charged to the pixels, the first frames'
    // uploads made the tier look dearer than it draws, and a tier held near on that rate is not
    // measured again (ErrorBudgetViews::keepAffordableBakes). Never below 1 % of the far pass.
    const double blitMs =
        sample.blitMs > 0.0 ? std::max(sample.blitMs - sample.farSnapshotsMs, 0.01 * sample.blitMs)
                            : 0.0;
    const bool wantFar = blitMs > 0.0;
    using Sums = std::pair<double, double>; // near cost units, far rectangle pixels
    const Sums sums =
        !(wantNear || wantFar)
            ? Sums{0.0, 0.0}
            : tbb::parallel_deterministic_reduce(
                  tbb::blocked_range<std::size_t>(0, visible.size(), 1024), Sums{0.0, 0.0},
                  [&](const auto& r, Sums acc) {
                      for (std::size_t k = r.begin(); k != r.end(); ++k) {
                          const std::uint32_t i = visible[k];
                          if (i >= sprites.size() || i >= plan.size()) continue;
                          if (wantNear && plan[i].drawsNear())
                              acc.first += nearCostUnits(sprites[i], rate);
                          if (wantFar && plan[i].drawsFar())
                              acc.second += double(rectPixels(sprites[i]));
                      }
                      return acc;
                  },
                  [](Sums a, const Sums& b) {
                      return Sums{a.first + b.first, a.second + b.second};
                  });
    const double nearUnits = sums.first, farPx = sums.second;
    // Running averages: each frame moves the estimate a third of the way to its own figure, so
    // one slow frame (another process on the cores) does not swing the next frame's plan.
    const auto blend = [](double& average, double sample) {
        average = average > 0.0 ? average + (sample - average) / 3.0 : sample;
    };
    // What a bake costs must not depend on what the on-disk store holds, or the cost bound
    // gives up bakes that a render without the directory keeps, and the image depends on which
    // process baked what (issue 28). So the far lookups' time counts only in the bakes' share
    // of the work: not the store's reads and writes, and not the Embree scene builds. A scene
    // is built once per model frame and serves every later bake of it, so which frame pays for
    // it depends on history: a process that read frame 0's snapshots from the directory built
    // the scenes for its first 2 bakes alone (46 ms, against 11 ms for a lone render's 142
    // bakes), learnt a 20x bake cost and gave up bakes the lone render kept.
    const double bakeShare = sample.sceneAndStoreMs > 0.0
                                 ? sample.bakeWorkMs / (sample.bakeWorkMs + sample.sceneAndStoreMs)
                                 : 1.0;
    if (sample.bakes > 0) blend(costs_.msPerBake, sample.bakeMs * bakeShare / sample.bakes);
    // Only the error-budget planner reads the near cost, and only its frames pay for measuring
    // the near tier's fixed cost: other frames (all-near, all-far, other metrics) are no sample.
    if (sample.planned && nearUnits > 0.0 && sample.nearMs > 0.0) {
        // What a sprite drawn far saves is its share of the near time above the tier's
        // per-frame cost (targets, clear, submit, readback), which stays while any sprite is
        // near, and above the voxel uploads, which a model pays once: charged to the sprites,
        // they made one near sprite look as dear as 4 ms of them. Never below 1 % of the
        // frame: a near sprite is not free, whatever the noise.
        const double fixedMs = nearFixedMs();
        const double spriteMs =
            std::max(sample.nearMs - sample.nearUploadMs - fixedMs, 0.01 * sample.nearMs);
        // A ratio of decayed sums, not an average of ratios: a frame with one small sprite near
        // (most frames of a far-heavy hybrid) measures its sprite time as a small difference
        // of two noisy times, and must weigh as little as the work it did. The renderer's first
        // near frame is no sample: lavapipe compiles its pipelines in it.
        if (nearFramesSeen_++ > 0) {
            nearSums_ = {nearSums_.ms * (2.0 / 3.0) + spriteMs,
                         nearSums_.units * (2.0 / 3.0) + nearUnits};
            costs_.nearMsPerUnit = nearSums_.ms / nearSums_.units;
        }
    }
    if (farPx > 0.0 && blitMs > 0.0) blend(costs_.blitMsPerPx, blitMs / farPx);
    if (sample.planned) blend(costs_.planMs, sample.planMs);
}

} // namespace voxtier
