#pragma once
// Pops (DESIGN.md §8, pop magnitude): what one entity's switch (of tier, of far view, or a step
// of a cross-fade) changes in the image, at the frame it happens and with that frame's camera, so
// that the camera's own motion is not counted. Two measures of each switch:
// - alone: the entity drawn by itself with its previous plan and with its new one. What the
//   switch does to the entity, wherever it stands.
// - seen: the frame drawn both ways, every other entity as this frame plans it, with the backdrop.
//   What a viewer sees change, occlusion included: an entity behind another pops unseen, and a
//   pixel it uncovers shows what the frame shows there. Only the entities whose screen
//   rectangles overlap the switching one's are drawn: no other can cover or show through its
//   pixels, and min-z with the id rule does not depend on which others are drawn, so the
//   rectangle's pixels are those of the whole frame drawn both ways.
// The columns of `voxtier render --pops` are kPopColumns (docs/outputs.md lists them; a test
// keeps the two in step).
#include "core/camera.hpp"
#include "core/image.hpp"
#include "core/scene.hpp"
#include "core/sprite.hpp"
#include "lod/frame_planner.hpp"

#include <algorithm>
#include <array>
#include <cstddef>
#include <cstdint>
#include <functional>
#include <span>
#include <string>
#include <vector>

namespace voxtier {

struct PopEvent {
    enum class Kind { TierSwitch, ViewSwitch, FadeStep };
    int frame = 0;
    std::uint32_t entity = 0;
    Kind kind = Kind::TierSwitch;
    double radiusPx = 0.0; ///< projected radius of the entity at the switch
    double vpxPx = 0.0;    ///< on-screen size of one of its virtual pixels (cellSizePx)
    // Alone: the entity by itself, previous plan against new.
    std::size_t changedPixels = 0; ///< pixels of the entity's footprint union that changed
    double changedFraction = 0.0;  ///< changedPixels / footprint union
    double displacementPx = 0.0;   ///< largest silhouette displacement (+inf: one side empty)
    // Seen: the frame, previous plan of this entity against new, the others as planned.
    std::size_t seenChangedPixels = 0; ///< pixels of the frame whose colour changed
    /// How far the silhouette moved where it can be seen: over the pixels the entity shows in one
    /// way only, the largest distance to its footprint (alone) the other way; at most
    /// displacementPx, 0 where it is hidden both ways.
    double seenDisplacementPx = 0.0;

    /// The displacements in virtual pixels, or in screen pixels where a virtual pixel is smaller
    /// than one (the unit of the error budget and of the status line's predicted displacement,
    /// lod/error_budget.hpp): a one-pixel move is never more than one.
    double displacementVpx() const { return displacementPx / std::max(vpxPx, 1.0); }
    double seenDisplacementVpx() const { return seenDisplacementPx / std::max(vpxPx, 1.0); }
};
const char* toString(PopEvent::Kind k);

/// Draws `sprites` as `plan` says (element by element), composed by min-z, without the backdrop:
/// FrameRenderer's drawing.
using PlanDrawer = std::function<Image(const std::vector<SpriteSetup>& sprites,
                                       const std::vector<EntityPlan>& plan)>;

/// The pops of one frame: an event for each visible entity whose plan differs from the one it had
/// the frame before (`before`, by entity id; none when the counts differ). `sprites` and `now` are
/// this frame's, by entity id.
std::vector<PopEvent> measurePops(const Scene& scene, const CameraFrame& camera,
                                  std::span<const SpriteSetup> sprites,
                                  std::span<const EntityPlan> before,
                                  std::span<const EntityPlan> now, int frame,
                                  const PlanDrawer& draw);

/// One column of the --pops CSV: its name, its unit and what it holds (as docs/outputs.md has it).
struct PopColumn {
    const char* name;
    const char* unit;
    std::string (*text)(const PopEvent&);
};
extern const std::array<PopColumn, 12> kPopColumns;
/// "name,name,...", kPopColumns' names in order (no newline).
std::string popCsvHeader();
/// One event as CSV fields in kPopColumns' order (no newline).
std::string popCsvRow(const PopEvent& e);

/// The pops of a run in a few numbers: how many switches, the worst seen change in pixels and in
/// virtual pixels, and how many changed more than `thresholdPx` pixels of what is seen.
struct PopSummary {
    explicit PopSummary(std::size_t thresholdPx) : thresholdPx(thresholdPx) {}
    std::size_t thresholdPx;
    std::size_t events = 0, tierSwitches = 0, viewSwitches = 0, fadeSteps = 0;
    std::size_t seen = 0;          ///< events that changed any pixel of what is seen
    std::size_t overThreshold = 0; ///< events whose seenChangedPixels > thresholdPx
    std::size_t worstPixels = 0;   ///< the largest seenChangedPixels
    PopEvent worstPixelsEvent;
    double worstVpx = 0.0; ///< the largest finite seenDisplacementVpx
    PopEvent worstVpxEvent;
    /// Events where the entity has no pixel one way (displacement +inf): it appears or vanishes.
    std::size_t appearing = 0;

    void add(const PopEvent& e);
};

} // namespace voxtier
