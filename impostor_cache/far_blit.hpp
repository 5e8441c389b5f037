#pragma once
// The far tier's blit (DESIGN.md §4 with its [voxtier] refinement): every screen pixel of a
// sprite's rectangle takes the near lattice cell the near kernel computes for it
// (kernel::vtPixelCell, the same code), moves to that cell's centre on the sprite plane, and
// reads the snapshot cell under it. So the far sprite keeps the near tier's screen-aligned
// virtual-pixel grid, roll and in-plane rotation are corrected, and at a canonical view with a
// roll of a multiple of 90 degrees every read lands half a cell away from any snapshot cell
// boundary, which is why far == near there exactly.
#include "core/image.hpp"
#include "core/sprite.hpp"
#include "core/voxel_model.hpp"
#include "impostor_cache/snapshot.hpp"

#include <cstdint>
#include <span>

namespace voxtier {

struct FarSprite {
    const SpriteSetup* sprite = nullptr; ///< culled sprites (!visible()) draw nothing
    const Snapshot* snapshot = nullptr;  ///< of the sprite's model frame, any view
    const Palette* palette = nullptr;
};

struct FarBlitStats {
    std::uint64_t sprites = 0;       ///< sprites drawn
    std::uint64_t pixelsTested = 0;  ///< pixels of sprite rectangles evaluated
    std::uint64_t pixelsWritten = 0; ///< solid or outline snapshot cells read
    double milliseconds = 0.0;
};

/// The view the far tier shows for a sprite: w* = argmax w . (-d), d = sprite.lattice.dir
/// (the per-entity direction the near tier uses, so the tiers agree on it).
int chooseFarView(const SpriteSetup& sprite, ViewSet set);

/// Draws the sprites into `target` (keeping what it holds) with the shared depth/id rule,
/// TBB-parallel over rows, sprites bucketed by row like the reference renderer.
void blitFar(std::span<const FarSprite> sprites, Image& target, FarBlitStats* stats = nullptr);

} // namespace voxtier
