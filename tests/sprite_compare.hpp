#pragma once
// Two sprite set-ups compared bit for bit: what every path that sets sprites up another way (the
// sprite store, the SIMD set-up) must give against a fresh scalar setupSprite.
#include "core/sprite.hpp"

#include <gtest/gtest.h>

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

} // namespace voxtier::test
