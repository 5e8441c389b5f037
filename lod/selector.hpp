#pragma once
// The tier selector of CONTRACT.md §5: per-entity state with distance hysteresis, three
// metrics, optional angular hysteresis on the far tier's view choice, and an optional
// time-based cross-fade. Pure logic over per-entity inputs; it knows nothing of Vulkan or
// snapshots (the compositor passes in the numbers and the view directions it needs).
#include "core/scene.hpp"

#include <glm/glm.hpp>

#include <atomic>
#include <cstdint>
#include <span>
#include <vector>

namespace voxtier {

enum class Tier : std::uint8_t { Near = 0, Far = 1 };
const char* toString(Tier t);

/// What the selector needs to know about one entity this frame.
struct SelectorInput {
    double distance = 0.0; ///< metres, eye to model centre
    double radiusPx = 0.0; ///< projected bounding-sphere radius in pixels
    /// Cosine of the angle theta from the entity's view direction to the nearest snapshot view,
    /// in [-1, 1]: error_px's theta is std::acos of it. The cosine, not the angle, since most
    /// entities' comparisons are decided without it (TierSelector::step).
    double viewCos = 1.0;
    /// ErrorBudget: the predicted far displacement from the best view allowed, over the budget
    /// (lod/error_budget.hpp computes it; the selector only compares it).
    double budgetShare = 0.0;
};

/// The value compared against near_at / far_at for `metric`.
/// ErrorPx is the predicted view-quantisation error r_px * sin(theta) (CONTRACT.md §5), with
/// theta = std::acos(viewCos).
double selectorMetric(SelectorMetric metric, const SelectorInput& in);

/// Where selectorMetric(metric, in) lies against `threshold`: -1 below it, 0 equal, +1 above,
/// always the sign of the IEEE value's difference. Under error_px it is found, where it can be,
/// without computing that value (metricSideFast); elsewhere by computing it.
int metricSide(SelectorMetric metric, const SelectorInput& in, double threshold);
/// error_px's side of `threshold` where a bound decides it without std::acos and std::sin: for a
/// cosine c in [0.5, 1] (the nearest of a view set's views is never 60 degrees away),
/// r * sqrt((1 - c)(1 + c)) is r * sin(acos(c)) to within a few units in the last place of each
/// rounding (1 - c is exact there, and theta * cot(theta) <= 1 carries acos's error through sin
/// unenlarged). More than kErrorPxSlack (relative) from a positive, finite threshold, both values
/// lie on the same side of it. -1 or +1 when decided, 0 when only the IEEE value can tell.
int metricSideFast(const SelectorInput& in, double threshold);
/// The decided region's relative distance from a threshold: ~10^6 times the bound above.
inline constexpr double kErrorPxSlack = 1e-9;

struct SelectorStats {
    int nearCount = 0, farCount = 0;
    int switchesToFar = 0, switchesToNear = 0;
    int viewChanges = 0; ///< far entities whose snapshot view changed (filled by the caller
                         ///< from TierSelector::viewChangesThisFrame after choosing views)
    int fading = 0;      ///< entities inside a cross-fade
};

/// Per-entity state. An entity's tier changes only on a crossing of its threshold:
///   grows-with-distance metric: near -> far when m > far_at;  far -> near when m < near_at
///   shrinks-with-distance metric: near -> far when m < far_at; far -> near when m > near_at
/// Hitting a threshold exactly does not switch (strict comparisons), so the outcome at the
/// threshold is deterministic. The first frame assigns tiers without counting switches:
/// an entity starts near unless its metric is already past far_at.
class TierSelector {
  public:
    explicit TierSelector(const SelectorConfig& config = {});

    const SelectorConfig& config() const { return config_; }
    /// Advances one frame. `inputs[i]` describes entity i; the entity count may not change
    /// between frames except through reset(). Parallel over the entities.
    SelectorStats update(std::span<const SelectorInput> inputs);
    /// Advances one frame for the entities `ids` alone (ascending or not): every other entity
    /// must be settled (settled()) with the input it had last frame, for which update() would
    /// change nothing. The counts are the listed entities' (nearCount, farCount included).
    SelectorStats update(std::span<const SelectorInput> inputs, std::span<const std::uint32_t> ids);
    /// update() for a caller that steps the entities inside a pass of its own (the frame
    /// planner's error_px plan derives each entity's inputs, steps it and chooses its far view
    /// in one pass over the entities). beginFrame starts a frame of `entities` (`partial`: of
    /// some of them, the rest settled, as update(inputs, ids)) and returns whether it is the
    /// first, whose tiers come from the metric alone; then stepEntity once for each entity the
    /// frame moves, concurrently for different entities, each thread summing its own stats.
    bool beginFrame(std::size_t entities, bool partial = false);
    void stepEntity(std::size_t i, const SelectorInput& in, bool first, SelectorStats& st) {
        step(i, in, first, st);
    }
    /// SelectorStats summed (what a pass that steps the entities joins its threads' stats with).
    static SelectorStats sum(SelectorStats a, const SelectorStats& b);
    void reset();
    /// Whether `entity` is outside a cross-fade: given last frame's input again, a frame changes
    /// nothing of its state (a switch needs a crossing, and near_at and far_at are apart).
    bool settled(std::size_t entity) const { return state_[entity].fadeLeft <= 0; }

    Tier tier(std::size_t entity) const { return state_[entity].tier; }
    std::size_t size() const { return state_.size(); }

    /// Cross-fade (config.crossfadeFrames > 0): after a switch, for that many frames the
    /// entity is drawn by both tiers and the compositor shows a dithered mix. Returns true
    /// while fading; `fraction` is the share of pixels that already show the new tier.
    bool fading(std::size_t entity, float* fraction, Tier* from) const;

    /// Far view choice with angular hysteresis: the view maximising w.towardViewer, except
    /// that the entity keeps its current view until another one is closer by more than
    /// config.viewHysteresisDeg. Ties go to the lowest view index. Counts view changes.
    /// Entities may choose their views concurrently (each touches its own state).
    int chooseView(std::size_t entity, glm::dvec3 towardViewer, std::span<const glm::dvec3> views);
    /// The same, where `nearest` is already known to be the view maximising w.towardViewer
    /// (ties to the lowest index, as nearestView finds it).
    int chooseView(std::size_t entity, glm::dvec3 towardViewer, std::span<const glm::dvec3> views,
                   int nearest);
    /// View changes counted by chooseView since the last update().
    int viewChangesThisFrame() const {
        return viewChangesThisFrame_.load(std::memory_order_relaxed);
    }

  private:
    struct State {
        Tier tier = Tier::Near;
        Tier fadeFrom = Tier::Near;
        int fadeLeft = 0; ///< frames of cross-fade still to show
        int view = -1;
    };
    /// Whether the metric is past far_at (near_at) in the direction that sends an entity far
    /// (near): strictly, so that a metric exactly at a threshold does not switch.
    bool pastFar(const SelectorInput& in) const;
    bool pastNear(const SelectorInput& in) const;
    /// One entity's frame (`first`: the tier from the metric alone, nothing counted).
    void step(std::size_t i, const SelectorInput& in, bool first, SelectorStats& st);

    SelectorConfig config_;
    std::vector<State> state_;
    bool initialised_ = false;
    std::atomic<int> viewChangesThisFrame_{0};
};

/// Ordered-dither threshold in (0, 1) for pixel (x, y) (4x4 Bayer matrix; the kernel's
/// vtDitherThreshold, which every tier applies while drawing): a cross-fade at fraction f shows
/// the new tier where threshold < f, so the pattern is stable over frames.
float ditherThreshold(int x, int y);

} // namespace voxtier
