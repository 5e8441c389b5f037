#pragma once
// Exact occlusion culling for the CPU tiers (DESIGN.md §6, "Occlusion"). Every sprite writes one
// depth, its centre's reversed-Z billboard depth, to every pixel it draws, and a pixel only ever
// moves nearer. So where every pixel of a screen tile already holds a depth strictly nearer than a
// sprite's, nothing the sprite could draw there wins the depth/id rule, whatever its dither,
// outline or id: the sprite can skip the tile, and a sprite all of whose tiles do so can be
// dropped before anything is baked or traced for it. Equal depths are never culled (the id rule
// decides them). Drawing front to back makes the tiles fill before the sprites behind them come.
#include "core/image.hpp"
#include "core/sprite.hpp"

#include <cstdint>
#include <span>
#include <utility>
#include <vector>

namespace voxtier {

/// Per 16x16 tile of an image, the farthest depth drawn, known only once every pixel of the tile
/// holds a sprite (an empty pixel is infinitely far). Kept lazily: a tile is re-read from the
/// image only when enough sprite rectangle has been drawn over it since its last reading to have
/// filled the pixels that were empty then, so a tile that fills is read about twice.
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

/// Splits a front-to-back order into runs drawn one after another, each tested as a whole against
/// what the runs before it drew: the first covers about half the image's area in sprite
/// rectangles, each later one as much rectangle area as all before it, so a frame takes
/// O(log(overdraw)) runs and a crowd's hidden majority meets a full set of tiles.
std::vector<std::pair<std::size_t, std::size_t>>
frontToBackRuns(std::span<const std::uint32_t> order, std::span<const SpriteSetup* const> sprites,
                std::size_t imagePixels);

} // namespace voxtier
