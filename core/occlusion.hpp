#pragma once
// Exact occlusion culling for the CPU tiers (CONTRACT.md §6, "Occlusion"). Every sprite writes one
// depth, its centre's reversed-Z billboard depth, to every pixel it draws, and a pixel only ever
// moves nearer. So where every pixel of a screen tile already holds a depth strictly nearer than a
// sprite's, nothing the sprite could draw there wins the depth/id rule, whatever its dither,
// outline or id: the sprite can skip the tile, and a sprite all of whose tiles do so can be
// dropped before anything is baked or traced for it. Equal depths are never culled (the id rule
// decides them). Drawing front to back makes the tiles fill before the sprites behind them come.
#include "core/image.hpp"
#include "core/key_sort.hpp"
#include "core/sprite.hpp"

#include <algorithm>
#include <cstdint>
#include <span>
#include <utility>
#include <vector>

namespace voxtier {

struct SpriteHistory; // core/sprite_store.hpp

/// Per 16x16 tile of an image, the farthest depth drawn, known only once every pixel of the tile
/// holds a sprite (an empty pixel is infinitely far). Kept lazily: a tile is re-read from the
/// image only when enough sprite rectangle has been drawn over it since its last reading to have
/// filled the pixels that were empty then (and, for a tile that keeps not filling, twice as much
/// as before), so a tile is read a few times at most.
class OcclusionTiles {
  public:
    static constexpr int kTile = 16;

    /// Tiles over `image` as it is now (every tile read on first use; `image` outlives this).
    explicit OcclusionTiles(const Image& image);

    int tileRows() const { return rows_; }
    /// Columns [x0, x1) of tile row `tileRow` a sprite at `depth` can still draw in: the tiles
    /// at either end that hide it are cut off. Reads stale tiles of that row first, so it must
    /// not run while another thread draws into that tile row.
    std::pair<int, int> visibleColumns(int tileRow, int x0, int x1, float depth);
    /// Whether some pixel of tile (tileRow, x / kTile) may still take a sprite at `depth`.
    bool tileOpen(int tileRow, int x, float depth);
    /// A sprite drew columns [x0, x1) of `rows` rows of tile row `tileRow` (its rectangle there,
    /// an upper bound on the pixels it filled).
    void drawn(int tileRow, int x0, int x1, int rows);
    /// Whether the tiles already hide every pixel of `rect` (x0, y0, x1, y1, half-open) from a
    /// sprite at `depth`. Reads stale tiles of the rectangle first (not thread-safe with
    /// drawing).
    bool hides(glm::ivec4 rect, float depth);

  private:
    struct Tile {
        float farthest = 0.0f; ///< the least depth in the tile once it is full, else 0
        int empty = 0;         ///< empty pixels at the last reading
        int drawnSince = 0;    ///< rectangle pixels drawn over the tile since then
        int reread = 0;        ///< read again after at least this many (occlusion.cpp)
        bool read = false;
    };
    Tile& tile(int row, int col) { return tiles_[std::size_t(row) * std::size_t(cols_) + col]; }
    /// The tile's farthest depth, re-read from the image if it may have filled since.
    float farthest(int row, int col);

    const Image* image_;
    int cols_ = 0, rows_ = 0;
    std::vector<Tile> tiles_;
};

/// The order the culling tiers draw in: nearest first (larger reversed-Z depth), equal depths by
/// ascending entity id, so a sprite is only ever tested against sprites in front of it.
/// Returns indices into `sprites` of the visible ones.
std::vector<std::uint32_t> frontToBack(std::span<const SpriteSetup* const> sprites);
/// The order a tier draws in: frontToBack when it culls, else the visible sprites as given.
std::vector<std::uint32_t> drawOrder(std::span<const SpriteSetup* const> sprites, bool cull);

/// The working arrays of an order (the keys and the sort's scratch), kept by a tier that orders
/// its sprites every frame: the forms below allocate nothing once they have grown, where the
/// forms above allocate and fill their arrays afresh each call (3 MB at 100,000 sprites).
struct DrawOrderBuffers {
    std::vector<KeyIndex> keyed;
    KeyIndexScratch scratch;
};
/// frontToBack and drawOrder into `order`, with the working arrays of `buffers`. With `history`,
/// a sprite of its store's current array has its visibility and depth read from the history's
/// per-entity arrays (SpriteHistory::visible, depths) instead of from the sprite: the same order.
void frontToBack(std::span<const SpriteSetup* const> sprites, DrawOrderBuffers& buffers,
                 std::vector<std::uint32_t>& order, const SpriteHistory* history = nullptr);
void drawOrder(std::span<const SpriteSetup* const> sprites, bool cull, DrawOrderBuffers& buffers,
               std::vector<std::uint32_t>& order, const SpriteHistory* history = nullptr);

/// The run size the tiers use: half the image in sprite rectangle area. Smaller runs cull more
/// (each sprite meets tiles filled closer in front of it) and pay more per-run overhead (a
/// parallel pass, a snapshot lookup round); half a screen keeps a frame to a few runs of drawn
/// sprites, since the hidden ones never join a run.
inline std::size_t occlusionRunPixels(std::size_t imagePixels) {
    return std::max<std::size_t>(imagePixels / 2, 1024);
}

/// Draws the sprites `order` lists (front to back, from frontToBack) in runs: each sprite is
/// first tested whole against `tiles`, and the ones they hide are dropped; the others gather into
/// runs of about `runPixels` of rectangle area, and `drawRun(span of sprite indices)` draws each
/// run (and tells `tiles` what it drew) before the next sprites are tested. So a sprite meets every
/// tile the runs before it filled, and a crowd's hidden majority is dropped without being drawn.
/// Without tiles, one run of everything. Returns how many sprites were dropped.
template <class DrawRun>
std::size_t drawFrontToBack(std::span<const std::uint32_t> order,
                            std::span<const SpriteSetup* const> sprites, OcclusionTiles* tiles,
                            std::size_t runPixels, DrawRun&& drawRun) {
    if (!tiles) {
        if (!order.empty()) drawRun(order);
        return 0;
    }
    std::vector<std::uint32_t> run;
    std::size_t culled = 0, area = 0;
    for (const std::uint32_t i : order) {
        const SpriteSetup& s = *sprites[i];
        if (tiles->hides(s.screenRect, s.gpu.depth)) {
            ++culled;
            continue;
        }
        run.push_back(i);
        area += std::size_t(std::max(0, s.screenRect.z - s.screenRect.x)) *
                std::size_t(std::max(0, s.screenRect.w - s.screenRect.y));
        if (area >= runPixels) {
            drawRun(std::span<const std::uint32_t>(run));
            run.clear();
            area = 0;
        }
    }
    if (!run.empty()) drawRun(std::span<const std::uint32_t>(run));
    return culled;
}

} // namespace voxtier
