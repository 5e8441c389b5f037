#include "impostor_cache/far_frame.hpp"

#include "core/stopwatch.hpp"

#include <tbb/parallel_for.h>

#include <algorithm>
#include <chrono>
#include <map>
#include <tuple>

namespace voxtier {

void drawFarSprites(const std::vector<std::shared_ptr<VoxelModel>>& models,
                    std::span<const FarRequest> requests, SnapshotCache& cache, ViewSet set,
                    Image& target, FarFrameStats* stats, const FarBlitOptions& blitOptions) {
    const auto t0 = std::chrono::steady_clock::now();
    const SnapshotCacheCounters before = cache.counters();
    // Distinct (model, frame, view, sigma) of the visible sprites; each is looked up (and baked)
    // once, in parallel, then shared by every sprite that shows it.
    using Need = std::tuple<int, int, int, int, int, double>; // model, frame, view x y z, sigma
    std::map<Need, std::size_t> slot;
    std::vector<Need> needs;
    std::vector<std::size_t> spriteSlot(requests.size(), SIZE_MAX);
    for (std::size_t r = 0; r < requests.size(); ++r) {
        const SpriteSetup* sp = requests[r].sprite;
        if (!sp || !sp->visible()) continue;
        const glm::ivec3 view =
            requests[r].view.value_or(viewIdOf(set, chooseFarView(*sp, set))).lattice;
        const Need n{sp->model, sp->frame, view.x, view.y, view.z, sp->lattice.sigma};
        auto [it, inserted] = slot.emplace(n, needs.size());
        if (inserted) needs.push_back(n);
        spriteSlot[r] = it->second;
    }
    std::vector<std::shared_ptr<const Snapshot>> snaps(needs.size());
    tbb::parallel_for(std::size_t(0), needs.size(), [&](std::size_t i) {
        const auto [m, f, x, y, z, sigma] = needs[i];
        snaps[i] = cache.get(*models.at(std::size_t(m)), f, ViewId{{x, y, z}}, sigma);
    });
    const double ensureMs = msSince(t0);

    std::vector<FarSprite> draws;
    draws.reserve(requests.size());
    for (std::size_t r = 0; r < requests.size(); ++r) {
        if (spriteSlot[r] == SIZE_MAX) continue;
        const SpriteSetup* sp = requests[r].sprite;
        draws.push_back(
            {sp, snaps[spriteSlot[r]].get(), &models.at(std::size_t(sp->model))->palette()});
    }
    FarBlitStats blit;
    blitFar(draws, target, &blit, blitOptions);
    if (stats) {
        stats->sprites += draws.size();
        stats->snapshotsUsed += needs.size();
        const SnapshotCacheCounters after = cache.counters();
        stats->bakes += after.bakes - before.bakes;
        stats->scenesBuilt += after.scenesBuilt - before.scenesBuilt;
        stats->refreshes += after.refreshes - before.refreshes;
        stats->incrementalRefreshes += after.incrementalRefreshes - before.incrementalRefreshes;
        stats->cellsRetraced += after.cellsRetraced - before.cellsRetraced;
        stats->ensureMs += ensureMs;
        stats->blit.sprites += blit.sprites;
        stats->blit.pixelsTested += blit.pixelsTested;
        stats->blit.pixelsWritten += blit.pixelsWritten;
        stats->blit.milliseconds += blit.milliseconds;
    }
}

} // namespace voxtier
