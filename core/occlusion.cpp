#include "core/occlusion.hpp"

#include "core/key_sort.hpp"
#include "core/sprite_store.hpp"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/parallel_reduce.h>

#include <algorithm>
#include <bit>
#include <limits>

namespace voxtier {

namespace {
/// A tile is read again only once this many rectangle pixels have been drawn over it since the
/// last reading, even if fewer were empty, and each reading that finds it still open doubles the
/// amount: a tile that never fills (sky between two silhouettes) would otherwise be re-read for
/// every small sprite over it (in the tank army the readings cost a third of the blit). Costs
/// culling only, never a pixel.
constexpr int kFirstReread = 64;
constexpr int kMaxReread = 1 << 16;
} // namespace

OcclusionTiles::OcclusionTiles(const Image& image)
    : image_(&image), cols_((image.width + kTile - 1) / kTile),
      rows_((image.height + kTile - 1) / kTile), tiles_(std::size_t(cols_) * std::size_t(rows_)) {}

float OcclusionTiles::farthest(int row, int col) {
    Tile& t = tile(row, col);
    if (t.read && (t.empty == 0 || t.drawnSince < std::max(t.empty, t.reread)))
        return t.empty == 0 ? t.farthest : 0.0f;
    const int x0 = col * kTile, x1 = std::min(x0 + kTile, image_->width);
    const int y0 = row * kTile, y1 = std::min(y0 + kTile, image_->height);
    int empty = 0;
    float least = std::numeric_limits<float>::infinity();
    for (int y = y0; y < y1; ++y) {
        const float* d = image_->depth.data() + image_->index(0, y);
        for (int x = x0; x < x1; ++x) {
            // No sprite writes a depth <= 0 (zNear / viewDepth): such a pixel is empty.
            empty += !(d[x] > 0.0f);
            least = std::min(least, d[x]);
        }
    }
    t = {empty == 0 ? least : 0.0f, empty, 0,
         t.read ? std::min(2 * t.reread, kMaxReread) : kFirstReread, true};
    return t.farthest;
}

bool OcclusionTiles::tileOpen(int tileRow, int x, float depth) {
    return !(farthest(tileRow, x / kTile) > depth);
}

std::pair<int, int> OcclusionTiles::visibleColumns(int tileRow, int x0, int x1, float depth) {
    while (x0 < x1 && !tileOpen(tileRow, x0, depth)) x0 = (x0 / kTile + 1) * kTile;
    while (x0 < x1 && !tileOpen(tileRow, x1 - 1, depth)) x1 = ((x1 - 1) / kTile) * kTile;
    return {x0, std::max(x0, x1)};
}

void OcclusionTiles::drawn(int tileRow, int x0, int x1, int rows) {
    for (int x = x0; x < x1;) {
        const int end = std::min(x1, (x / kTile + 1) * kTile);
        tile(tileRow, x / kTile).drawnSince += (end - x) * rows;
        x = end;
    }
}

bool OcclusionTiles::hides(glm::ivec4 rect, float depth) {
    if (rect.x >= rect.z || rect.y >= rect.w) return false;
    const int r1 = std::min((rect.w - 1) / kTile, rows_ - 1);
    const int c1 = std::min((rect.z - 1) / kTile, cols_ - 1);
    for (int r = rect.y / kTile; r <= r1; ++r)
        for (int c = rect.x / kTile; c <= c1; ++c)
            if (!(farthest(r, c) > depth)) return false;
    return true;
}

void frontToBack(std::span<const SpriteSetup* const> sprites, DrawOrderBuffers& buffers,
                 std::vector<std::uint32_t>& order, const SpriteHistory* history) {
    // One 64-bit key per sprite: the depth's bits inverted (positive floats order like their
    // bits, so this puts nearer first), then the entity id; the index rides along. The keys are
    // read in parallel: at 100,000 sprites reading each one's depth is a cache miss apiece, which
    // one core paid serially (a third of the near tier's host recording); with the store's
    // history they are read from its per-entity arrays, in entity order. Hidden sprites get the
    // greatest key and are cut from the end after the sort.
    constexpr std::uint64_t kHidden = std::numeric_limits<std::uint64_t>::max();
    const auto shown = [&](std::uint32_t i) { return sprites[i] && sprites[i]->visible(); };
    std::vector<KeyIndex>& keyed = buffers.keyed;
    keyed.resize(sprites.size());
    // Whether the shown sprites' ids ascend with their index (a frame's sprites usually come in
    // entity order): then the id in a key only breaks ties the index breaks the same way, and
    // the sort spares its digits (sortKeyIndexPairs's tieBits). Not where a shown sprite's key
    // reaches kHidden's depth half (a depth of 0), which the hidden pairs' ids would not follow.
    const AscendingIds ids = tbb::parallel_reduce(
        tbb::blocked_range<std::uint32_t>(0, std::uint32_t(sprites.size()), 256), AscendingIds{},
        [&](const auto& r, AscendingIds seen) {
            for (std::uint32_t i = r.begin(); i != r.end(); ++i) {
                const SpriteHistory::OrderInputs in =
                    sprites[i] ? SpriteHistory::orderInputs(history, *sprites[i])
                               : SpriteHistory::OrderInputs{};
                if (!in.visible) {
                    keyed[i] = {kHidden, i};
                    continue;
                }
                const std::uint32_t depthBits =
                    std::bit_cast<std::uint32_t>(std::max(in.depth, 0.0f));
                keyed[i] = {(std::uint64_t(~depthBits) << 32) | in.id, i};
                seen.add(in.id);
                seen.ascending = seen.ascending && depthBits != 0;
            }
            return seen;
        },
        AscendingIds::join);
    // (key, index) pairs are distinct, so the order has one answer, whichever sort finds it.
    sortKeyIndexPairs(keyed, buffers.scratch, ids.ascending ? 32 : 0);
    // The hidden sort last, after any visible sprite whose key is the greatest too (depth 0 and
    // the greatest id), which stays in its place among them.
    const auto tail = std::lower_bound(keyed.begin(), keyed.end(), KeyIndex(kHidden, 0));
    order.resize(std::size_t(tail - keyed.begin()));
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, order.size(), 4096), [&](const auto& r) {
        for (std::size_t k = r.begin(); k != r.end(); ++k) order[k] = keyed[k].second;
    });
    for (auto it = tail; it != keyed.end(); ++it)
        if (shown(it->second)) order.push_back(it->second);
}

void drawOrder(std::span<const SpriteSetup* const> sprites, bool cull, DrawOrderBuffers& buffers,
               std::vector<std::uint32_t>& order, const SpriteHistory* history) {
    if (cull) return frontToBack(sprites, buffers, order, history);
    order.clear();
    for (std::uint32_t i = 0; i < sprites.size(); ++i)
        if (sprites[i] && sprites[i]->visible()) order.push_back(i);
}

std::vector<std::uint32_t> frontToBack(std::span<const SpriteSetup* const> sprites) {
    DrawOrderBuffers buffers;
    std::vector<std::uint32_t> order;
    frontToBack(sprites, buffers, order);
    return order;
}

std::vector<std::uint32_t> drawOrder(std::span<const SpriteSetup* const> sprites, bool cull) {
    DrawOrderBuffers buffers;
    std::vector<std::uint32_t> order;
    drawOrder(sprites, cull, buffers, order);
    return order;
}

} // namespace voxtier
