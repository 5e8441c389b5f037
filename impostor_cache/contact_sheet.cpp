#include "impostor_cache/contact_sheet.hpp"

#include "impostor_cache/bitmap_font.hpp"

#include <algorithm>
#include <cmath>
#include <string>

namespace voxtier {

Image makeContactSheet(const std::vector<std::shared_ptr<const Snapshot>>& snaps,
                       const Palette& palette, const ContactSheetOptions& o) {
    if (snaps.empty()) return Image(1, 1, o.background);
    int maxW = 1, maxH = 1;
    for (const auto& s : snaps)
        maxW = std::max(maxW, s->width()), maxH = std::max(maxH, s->height());
    const int scale = std::max(1, o.maxTilePixels / std::max(maxW, maxH));
    const int cols = o.columns > 0 ? o.columns : int(std::ceil(std::sqrt(double(snaps.size()))));
    const int rows = (int(snaps.size()) + cols - 1) / cols;
    const int label = kGlyphHeight + 4;
    const int tileW = std::max(maxW * scale, textWidth("000 (+0,+0,+0)")) + 8;
    const int tileH = maxH * scale + label + 8;
    Image img(cols * tileW, rows * tileH, o.background);

    // A fixed light in voxel space (from the upper front right), relative to nothing the scene
    // holds: the sheet shows shape and face orientation, not a scene's lighting.
    Light light;
    EntityPose pose;
    pose.worldFromVoxelRotation = worldFromVoxelSwizzle();
    const auto factors = faceLightFactors(light, pose);

    for (std::size_t n = 0; n < snaps.size(); ++n) {
        const Snapshot& s = *snaps[n];
        const int tx = int(n) % cols * tileW, ty = int(n) / cols * tileH;
        const glm::ivec3 lp = s.view.lattice;
        auto sgn = [](int v) { return (v > 0 ? "+" : "") + std::to_string(v); };
        const std::string text =
            std::to_string(n) + " (" + sgn(lp.x) + "," + sgn(lp.y) + "," + sgn(lp.z) + ")";
        drawText(img, tx + 4, ty + 3, text, o.text);
        // Tile area, centred; snapshot row j grows upwards, image rows downwards.
        const int ox = tx + (tileW - s.width() * scale) / 2,
                  oy = ty + label + 4 + (maxH - s.height()) * scale / 2;
        for (int y = ty + label + 2; y < ty + tileH - 2; ++y)
            for (int x = tx + 2; x < tx + tileW - 2; ++x)
                img.color[img.index(x, y)] = o.tileBackground;
        for (int j = 0; j < s.height(); ++j)
            for (int i = 0; i < s.width(); ++i) {
                const SnapshotCell c =
                    s.cells[std::size_t(j) * std::size_t(s.width()) + std::size_t(i)];
                if (c.code == snapshot_code::kEmpty) continue;
                const Rgba8 color = snapshot_code::isSolid(c.code)
                                        ? kernel::vtLit(palette.colors[c.index],
                                                        factors[snapshot_code::face(c.code)])
                                        : kernel::VT_OUTLINE_RGBA;
                const int px = ox + i * scale, py = oy + (s.height() - 1 - j) * scale;
                for (int sy = 0; sy < scale; ++sy)
                    for (int sx = 0; sx < scale; ++sx)
                        img.color[img.index(px + sx, py + sy)] = color;
            }
    }
    return img;
}

} // namespace voxtier
