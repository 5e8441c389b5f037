// Pops, alone and seen (compose/pop_measure.hpp).
#include "compose/pop_measure.hpp"

#include "compose/backdrop.hpp"
#include "compose/error_metrics.hpp"
#include "core/view_set.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <optional>

namespace voxtier {

const char* toString(PopEvent::Kind k) {
    switch (k) {
    case PopEvent::Kind::TierSwitch:
        return "tier";
    case PopEvent::Kind::ViewSwitch:
        return "view";
    case PopEvent::Kind::FadeStep:
        return "fade";
    }
    return "?";
}

namespace {

bool overlap(const glm::ivec4& a, const glm::ivec4& b) {
    return a.x < b.z && b.x < a.z && a.y < b.w && b.y < a.w;
}

/// `plan` as a frame before this one planned it, drawable with this frame's sprite: a far plan
/// without a view (the selector's, before the budget gave views) takes the nearest one.
EntityPlan drawable(EntityPlan plan, const SpriteSetup& sprite, ViewSet set) {
    if (plan.drawsFar() && !plan.view)
        plan.view = viewIdOf(set, nearestView(set, -sprite.lattice.dir));
    return plan;
}

/// How far the entity's silhouette moved where it can be seen: over the pixels of `rect` where
/// it shows in one of the frames drawn both ways (`seenOld`, `seenNew`) but not in the other, the
/// largest distance to its footprint drawn alone the other way (`aloneOld`, `aloneNew`). So a
/// switch moves what is seen by no more than it moves the entity, and a pixel that shows through
/// a gap in an occluder counts by the move at that pixel, not by the distance to the entity's
/// next visible fragment. 0 where no visible pixel changes hands; +inf where the entity has no
/// pixel alone one way.
double seenDisplacement(const Image& aloneOld, const Image& aloneNew, const Image& seenOld,
                        const Image& seenNew, std::uint32_t id, const glm::ivec4& rect) {
    const int w = rect.z - rect.x, h = rect.w - rect.y;
    const auto cells = std::size_t(w) * std::size_t(h);
    std::vector<std::uint8_t> footprintOld(cells), footprintNew(cells);
    std::vector<std::size_t> gained, lost; // cells shown only with the new plan / the old one
    for (int y = 0; y < h; ++y)
        for (int x = 0; x < w; ++x) {
            const std::size_t p = seenNew.index(rect.x + x, rect.y + y);
            const auto c = std::size_t(y) * std::size_t(w) + std::size_t(x);
            footprintOld[c] = aloneOld.id[p] == id;
            footprintNew[c] = aloneNew.id[p] == id;
            const bool shownOld = seenOld.id[p] == id, shownNew = seenNew.id[p] == id;
            if (shownNew && !shownOld) gained.push_back(c);
            if (shownOld && !shownNew) lost.push_back(c);
        }
    double worst = 0.0;
    if (!gained.empty()) {
        const std::vector<double> d = squaredDistanceTransform(footprintOld, w, h);
        for (std::size_t c : gained) worst = std::max(worst, d[c]);
    }
    if (!lost.empty()) {
        const std::vector<double> d = squaredDistanceTransform(footprintNew, w, h);
        for (std::size_t c : lost) worst = std::max(worst, d[c]);
    }
    return std::sqrt(worst);
}

} // namespace

std::vector<PopEvent> measurePops(const Scene& scene, const CameraFrame& cam,
                                  std::span<const SpriteSetup> sprites,
                                  std::span<const EntityPlan> before,
                                  std::span<const EntityPlan> now, int frame,
                                  const PlanDrawer& draw) {
    std::vector<PopEvent> pops;
    if (before.size() != now.size() || now.size() != sprites.size()) return pops;
    const ViewSet set = viewSetFromSize(scene.selector.viewSetSize);
    for (std::size_t i = 0; i < sprites.size(); ++i) {
        if (now[i] == before[i] || !sprites[i].visible()) continue;
        const SpriteSetup& sprite = sprites[i];
        const auto id = std::uint32_t(i);
        PopEvent e;
        e.frame = frame;
        e.entity = id;
        e.radiusPx = sprite.radiusPx;
        e.vpxPx = cellSizePx(sprite);
        e.kind = now[i].tier != before[i].tier ? PopEvent::Kind::TierSwitch
                 : (now[i].fade != before[i].fade || now[i].fadeFrom != before[i].fadeFrom)
                     ? PopEvent::Kind::FadeStep
                     : PopEvent::Kind::ViewSwitch;
        const EntityPlan old = drawable(before[i], sprite, set);
        const glm::ivec4 rect = sprite.screenRect;

        // Alone.
        const std::vector<SpriteSetup> alone = {sprite};
        const Image aloneOld = draw(alone, {old}), aloneNew = draw(alone, {now[i]});
        const auto err = entityErrors(aloneOld, aloneNew, {id}, rect);
        if (!err.empty()) {
            e.changedPixels = err[0].mismatched;
            e.changedFraction = err[0].mismatchFraction();
            e.displacementPx = err[0].silhouetteDisplacementPx;
        }

        // Seen: every visible entity whose rectangle meets this one's, as planned, this one
        // both ways.
        std::vector<SpriteSetup> near;
        std::vector<EntityPlan> plans;
        std::optional<std::size_t> self;
        for (std::size_t j = 0; j < sprites.size(); ++j) {
            if (!sprites[j].visible() || !overlap(sprites[j].screenRect, rect)) continue;
            if (j == i) self = near.size();
            near.push_back(sprites[j]);
            plans.push_back(now[j]);
        }
        if (!self) { // an empty rectangle: nothing of it on screen
            pops.push_back(e);
            continue;
        }
        Image after = draw(near, plans);
        plans[*self] = old;
        Image earlier = draw(near, plans);
        drawBackdrop(scene, cam, after);
        drawBackdrop(scene, cam, earlier);
        for (int y = rect.y; y < rect.w; ++y)
            for (int x = rect.x; x < rect.z; ++x)
                e.seenChangedPixels +=
                    earlier.color[after.index(x, y)] != after.color[after.index(x, y)];
        e.seenDisplacementPx = seenDisplacement(aloneOld, aloneNew, earlier, after, id, rect);
        pops.push_back(e);
    }
    return pops;
}

namespace {

std::string integer(std::size_t v) {
    return std::to_string(v);
}

std::string fixed(double v, int decimals) {
    if (std::isinf(v)) return "inf";
    char buf[64];
    std::snprintf(buf, sizeof buf, "%.*f", decimals, v);
    return buf;
}

} // namespace

// clang-format off
const std::array<PopColumn, 12> kPopColumns = {{
    {"frame",                 "",          [](const PopEvent& e) { return std::to_string(e.frame); }},
    {"entity",                "",          [](const PopEvent& e) { return std::to_string(e.entity); }},
    {"kind",                  "",          [](const PopEvent& e) { return std::string(toString(e.kind)); }},
    {"changed_pixels",        "pixels",    [](const PopEvent& e) { return integer(e.changedPixels); }},
    {"changed_fraction",      "fraction",  [](const PopEvent& e) { return fixed(e.changedFraction, 6); }},
    {"displacement_px",       "pixels",    [](const PopEvent& e) { return fixed(e.displacementPx, 3); }},
    {"radius_px",             "pixels",    [](const PopEvent& e) { return fixed(e.radiusPx, 3); }},
    {"vpx_px",                "pixels",    [](const PopEvent& e) { return fixed(e.vpxPx, 3); }},
    {"displacement_vpx",      "vpx",       [](const PopEvent& e) { return fixed(e.displacementVpx(), 3); }},
    {"seen_changed_pixels",   "pixels",    [](const PopEvent& e) { return integer(e.seenChangedPixels); }},
    {"seen_displacement_px",  "pixels",    [](const PopEvent& e) { return fixed(e.seenDisplacementPx, 3); }},
    {"seen_displacement_vpx", "vpx",       [](const PopEvent& e) { return fixed(e.seenDisplacementVpx(), 3); }},
}};
// clang-format on

std::string popCsvHeader() {
    std::string s;
    for (const PopColumn& c : kPopColumns) s += (s.empty() ? "" : ",") + std::string(c.name);
    return s;
}

std::string popCsvRow(const PopEvent& e) {
    std::string s;
    for (std::size_t k = 0; k < kPopColumns.size(); ++k)
        s += (k ? "," : "") + kPopColumns[k].text(e);
    return s;
}

void PopSummary::add(const PopEvent& e) {
    ++events;
    ++(e.kind == PopEvent::Kind::TierSwitch   ? tierSwitches
       : e.kind == PopEvent::Kind::ViewSwitch ? viewSwitches
                                              : fadeSteps);
    seen += e.seenChangedPixels > 0;
    overThreshold += e.seenChangedPixels > thresholdPx;
    if (e.seenChangedPixels > worstPixels) worstPixels = e.seenChangedPixels, worstPixelsEvent = e;
    const double vpx = e.seenDisplacementVpx();
    if (std::isinf(vpx))
        ++appearing;
    else if (vpx > worstVpx)
        worstVpx = vpx, worstVpxEvent = e;
}

} // namespace voxtier
