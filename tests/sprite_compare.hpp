#pragma once
// Two sprite set-ups compared bit for bit: what every path that sets sprites up another way (the
// sprite store, the SIMD set-up) must give against a fresh scalar setupSprite.
#include "core/sprite.hpp"

#include <gtest/gtest.h>

#include <array>
#include <bit>
#include <cstdint>
#include <cstring>

namespace voxtier::test {

/// Field by field (SpriteSetup has padding; its SpriteGpu and quad have none and are compared
/// bytewise).
inline ::testing::AssertionResult sameSprite(const SpriteSetup& a, const SpriteSetup& b) {
    const auto& la = a.lattice;
    const auto& lb = b.lattice;
    const bool same =
        a.cull == b.cull && a.entityId == b.entityId && a.model == b.model && a.frame == b.frame &&
        a.pose.worldFromVoxelRotation == b.pose.worldFromVoxelRotation &&
        a.pose.position == b.pose.position && a.pose.anchor == b.pose.anchor &&
        a.pose.metresPerVoxel == b.pose.metresPerVoxel && la.dir == lb.dir &&
        la.right == lb.right && la.up == lb.up && la.centre == lb.centre && la.gU == lb.gU &&
        la.gV == lb.gV && la.sigma == lb.sigma && la.maxDim == lb.maxDim && la.dims == lb.dims &&
        la.cellRange == lb.cellRange && a.centreRel == b.centreRel && a.viewDepth == b.viewDepth &&
        a.distance == b.distance && a.radiusPx == b.radiusPx && a.screenRect == b.screenRect &&
        std::memcmp(&a.gpu, &b.gpu, sizeof a.gpu) == 0 &&
        std::memcmp(&a.quad, &b.quad, sizeof a.quad) == 0;
    if (same) return ::testing::AssertionSuccess();
    return ::testing::AssertionFailure()
           << "entity " << a.entityId << " differs from entity " << b.entityId << "'s fresh set-up";
}

/// Two sprites' selection inputs, every double bit for bit (a sign of zero too: the planner's
/// tests and sums read them).
inline ::testing::AssertionResult sameSelection(const SpriteSelectionInputs& a,
                                                const SpriteSelectionInputs& b) {
    const auto bits = [](const SpriteSelectionInputs& s) {
        const glm::dvec3 d = s.displacement.lineOfSight();
        return std::array<std::uint64_t, 12>{
            std::bit_cast<std::uint64_t>(s.distance),
            std::bit_cast<std::uint64_t>(s.radiusPx),
            std::bit_cast<std::uint64_t>(s.towardViewer.x),
            std::bit_cast<std::uint64_t>(s.towardViewer.y),
            std::bit_cast<std::uint64_t>(s.towardViewer.z),
            std::bit_cast<std::uint64_t>(d.x),
            std::bit_cast<std::uint64_t>(d.y),
            std::bit_cast<std::uint64_t>(d.z),
            std::bit_cast<std::uint64_t>(s.displacement.sigmaDepth()),
            std::bit_cast<std::uint64_t>(s.cellSizePx),
            s.cells,
            s.rectPixels};
    };
    if (a.visible == b.visible && bits(a) == bits(b)) return ::testing::AssertionSuccess();
    const auto ba = bits(a), bb = bits(b);
    std::size_t k = 0;
    while (k < ba.size() && ba[k] == bb[k]) ++k;
    return ::testing::AssertionFailure()
           << "field " << k << ": "
           << "selection inputs differ: distance " << a.distance << " / " << b.distance
           << ", cell size " << a.cellSizePx << " / " << b.cellSizePx << ", visible " << a.visible
           << " / " << b.visible;
}

} // namespace voxtier::test
