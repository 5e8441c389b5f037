#pragma once
// The far tier's blit (CONTRACT.md §4, Blit): every screen pixel of a
// sprite's rectangle takes the near lattice cell the near kernel computes for it
// (kernel::vtPixelCell, the same code), moves to that cell's centre on the sprite plane, and
// reads the snapshot cell under it. So the far sprite keeps the near tier's screen-aligned
// virtual-pixel grid, roll and in-plane rotation are corrected, and at a canonical view with a
// roll of a multiple of 90 degrees every read lands half a cell away from any snapshot cell
// boundary, which is why far == near there exactly.
#include "core/image.hpp"
#include "core/occlusion.hpp"
#include "core/sprite.hpp"
#include "core/voxel_model.hpp"
#include "impostor_cache/far_stats.hpp"
#include "impostor_cache/snapshot.hpp"

#include <cmath>
#include <cstdint>
#include <span>

namespace voxtier {

struct FarSprite {
    const SpriteSetup* sprite = nullptr; ///< culled sprites (!visible()) draw nothing
    const Snapshot* snapshot = nullptr;  ///< of the sprite's model frame, any view
    const Palette* palette = nullptr;
};

/// Which snapshot cell the blit reads for near cell (i, j): the centre of the near cell on the
/// sprite plane, (gU + (i+½)/σ) right + (gV + (j+½)/σ) up, expressed on the snapshot lattice,
/// floor(σs (q·right_s − gU_s)) and floor(σs (q·up_s − gV_s)). Affine in (i, j), so it is set up
/// once per sprite (double) and costs two multiply-adds per axis and cell.
struct SnapshotCellMap {
    double u0 = 0, ui = 0, uj = 0, v0 = 0, vi = 0, vj = 0;
    glm::ivec2 operator()(glm::ivec2 cell) const {
        return {floorToInt(u0 + ui * cell.x + uj * cell.y),
                floorToInt(v0 + vi * cell.x + vj * cell.y)};
    }
    /// floor() for |x| < 2^31, which every cell of a lattice of at most 256-voxel models at any
    /// sane sigma is. Without SSE4.1 (the x86-64 baseline) std::floor compiles to a slow sequence;
    /// this is a truncation and a compare.
    static int floorToInt(double x) {
        const int t = int(x);
        return t - (x < double(t));
    }
};
SnapshotCellMap snapshotCellMap(const SpriteLattice& nearLattice,
                                const SpriteLattice& snapshotLattice);

/// Which kernel evaluates the blit's pixels. Both write the same image, bit for bit (colour,
/// depth and id; tests/far_blit_simd_test.cpp); the scalar one is the reference the vectorised
/// one is tested against, and the way to measure what vectorising buys.
enum class FarBlitKernel {
    Simd,   ///< spans of 4-16 pixels at once, the widest SIMD target this CPU has (Highway)
    Scalar, ///< one pixel at a time: kernel::vtPixelCell, SnapshotCellMap, vtLit, writeIfNearer
};
struct FarBlitOptions {
    FarBlitKernel kernel = FarBlitKernel::Simd;
    /// Image rows per parallel task. A task draws every sprite touching its band, sprite by
    /// sprite, so a sprite's snapshot and the band's target rows stay in cache while it is drawn;
    /// 1 visits the sprites of each row in turn (the blit's layout before the band).
    int bandRows = 16;
    /// Exact occlusion culling (core/occlusion.hpp): sprites drawn front to back, and whatever
    /// the depth already drawn hides is skipped, whole sprites before their snapshots are looked
    /// up or baked. The same image either way; off by default, since on the bench scenes it
    /// costs more than it saves (CONTRACT.md §6, Occlusion).
    bool occlusionCull = false;
};

/// The SIMD target FarBlitKernel::Simd runs on this CPU (Highway's name: "AVX3", "AVX2",
/// "SSE4", "NEON", "EMU128" ...).
const char* farBlitSimdTarget();

/// The view the far tier shows for a sprite: w* = argmax w . (-d), d = sprite.lattice.dir
/// (the per-entity direction the near tier uses, so the tiers agree on it).
int chooseFarView(const SpriteSetup& sprite, ViewSet set);

/// Draws the sprites into `target` (keeping what it holds) with the shared depth/id rule,
/// TBB-parallel over bands of rows, sprites bucketed by band. The result does not depend on the
/// kernel, the band height or the order sprites are visited in (the depth/id rule decides).
/// With `tiles` (over `target`; ignored unless options.bandRows is a multiple of its tile), the
/// sprites are drawn front to back and the parts of each the tiles hide are skipped; the tiles
/// learn what was drawn. The image is the same either way.
void blitFar(std::span<const FarSprite> sprites, Image& target, FarBlitStats* stats = nullptr,
             const FarBlitOptions& options = {}, OcclusionTiles* tiles = nullptr);

} // namespace voxtier
