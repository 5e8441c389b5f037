#include "compose/frame_error.hpp"

#include "core/view_set.hpp"
#include "impostor_cache/far_frame.hpp"
#include "volumetric/reference_renderer.hpp"

#include <algorithm>
#include <cmath>

namespace voxtier {

namespace {

struct Accumulator {
    EntityErrorSummary s;
    std::size_t displaced = 0; ///< entities with a finite displacement (the mean's denominator)
    void add(const EntityError& e, double cellPx) {
        ++s.entities;
        const double m = e.mismatchFraction();
        s.meanMismatch += m;
        s.meanCoverageMismatch += e.coverageMismatchFraction();
        if (m > s.worstMismatch) s.worstMismatch = m, s.worstMismatchEntity = e.entity;
        if (!std::isfinite(e.silhouetteDisplacementPx)) {
            ++s.missing;
            return;
        }
        ++displaced;
        s.meanDisplacementPx += e.silhouetteDisplacementPx;
        s.worstDisplacementPx = std::max(s.worstDisplacementPx, e.silhouetteDisplacementPx);
        const double cells = e.silhouetteDisplacementPx / std::max(1.0, cellPx);
        s.overOneCell += cells > 1.0;
        if (cells > s.worstDisplacementCells)
            s.worstDisplacementCells = cells, s.worstDisplacementEntity = e.entity;
    }
    EntityErrorSummary done() {
        if (s.entities)
            s.meanMismatch /= double(s.entities), s.meanCoverageMismatch /= double(s.entities);
        if (displaced) s.meanDisplacementPx /= double(displaced);
        return s;
    }
};

} // namespace

EntityErrorSummary summarizeEntities(const std::vector<EntityError>& errors,
                                     std::span<const SpriteSetup> sprites) {
    Accumulator a;
    for (const EntityError& e : errors) a.add(e, cellSizePx(sprites[e.entity]));
    return a.done();
}

std::vector<EntityError> isolatedFarErrors(const Scene& scene, const CameraFrame& cam,
                                           std::span<const SpriteSetup> sprites,
                                           std::span<const EntityPlan> plan, SnapshotCache& cache) {
    // Passes of entities whose screen rectangles share no 8x8 tile.
    constexpr int kTile = 8;
    const int tw = (cam.width + kTile - 1) / kTile, th = (cam.height + kTile - 1) / kTile;
    std::vector<std::vector<std::uint8_t>> used;
    std::vector<std::vector<std::uint32_t>> passes;
    for (std::size_t i = 0; i < sprites.size() && i < plan.size(); ++i) {
        const SpriteSetup& s = sprites[i];
        if (!s.visible() || !plan[i].drawsFar()) continue;
        const glm::ivec4 r = s.screenRect;
        const int x0 = r.x / kTile, y0 = r.y / kTile, x1 = (r.z - 1) / kTile,
                  y1 = (r.w - 1) / kTile;
        auto fits = [&](const std::vector<std::uint8_t>& u) {
            for (int y = y0; y <= y1; ++y)
                for (int x = x0; x <= x1; ++x)
                    if (u[std::size_t(y * tw + x)]) return false;
            return true;
        };
        std::size_t p = 0;
        while (p < passes.size() && !fits(used[p])) ++p;
        if (p == passes.size())
            used.emplace_back(std::size_t(tw) * std::size_t(th), 0), passes.emplace_back();
        for (int y = y0; y <= y1; ++y)
            for (int x = x0; x <= x1; ++x) used[p][std::size_t(y * tw + x)] = 1;
        passes[p].push_back(s.entityId);
    }
    const ViewSet set = viewSetFromSize(scene.selector.viewSetSize);
    const Rgba8 bg = scene.render.background;
    Image truth(cam.width, cam.height, bg), test(cam.width, cam.height, bg);
    std::vector<EntityError> out;
    for (const auto& ids : passes) {
        std::vector<const SpriteSetup*> near;
        std::vector<FarRequest> far;
        for (std::uint32_t id : ids) {
            near.push_back(&sprites[id]);
            far.push_back({&sprites[id], plan[id].view});
        }
        renderReference(scene.models, near, truth);
        drawFarSprites(scene.models, far, cache, set, test);
        for (std::uint32_t id : ids) {
            const glm::ivec4 r = sprites[id].screenRect;
            const auto e = entityErrors(truth, test, {id}, r);
            if (!e.empty()) out.push_back(e.front());
            // Clear the rectangle for the next pass (cheaper than clearing the whole images).
            for (int y = r.y; y < r.w; ++y)
                for (int x = r.x; x < r.z; ++x) {
                    const std::size_t p = truth.index(x, y);
                    truth.color[p] = test.color[p] = bg;
                    truth.depth[p] = test.depth[p] = 0.0f;
                    truth.id[p] = test.id[p] = kernel::VT_NO_ENTITY;
                }
        }
    }
    return out;
}

FrameErrorReport measureFrameError(const Image& truth, const Image& test,
                                   std::span<const SpriteSetup> sprites,
                                   std::span<const EntityPlan> plan) {
    std::vector<std::uint32_t> ids;
    ids.reserve(sprites.size());
    for (const SpriteSetup& s : sprites)
        if (s.visible()) ids.push_back(s.entityId);
    const std::vector<EntityError> per = entityErrors(truth, test, ids);
    Accumulator all, far;
    for (const EntityError& e : per) {
        const SpriteSetup& s = sprites[e.entity];
        const double cell = cellSizePx(s);
        all.add(e, cell);
        if (e.entity < plan.size() && plan[e.entity].drawsFar()) far.add(e, cell);
    }
    FrameErrorReport r;
    r.all = all.done();
    r.far = far.done();
    const FrameError f = summarize(per, truth, test);
    r.rmse = f.rmse;
    r.psnr = f.psnr;
    r.changedPixels = f.changedPixels;
    r.differingPixels = diffImages(truth, test).pixelDiffs;
    return r;
}

} // namespace voxtier
