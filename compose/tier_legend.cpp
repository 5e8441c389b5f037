#include "compose/tier_legend.hpp"

#include <cstdint>
#include <string_view>

namespace voxtier {

namespace {

/// A 3x5 pixel font for the legend's letters: five rows of three bits, top row first.
std::array<std::uint8_t, 5> glyph(char ch) {
    switch (ch) {
    case 'N':
        return {0b110, 0b101, 0b101, 0b101, 0b101};
    case 'E':
        return {0b111, 0b100, 0b110, 0b100, 0b111};
    case 'A':
        return {0b010, 0b101, 0b111, 0b101, 0b101};
    case 'R':
        return {0b110, 0b101, 0b110, 0b101, 0b101};
    case 'F':
        return {0b111, 0b100, 0b110, 0b100, 0b100};
    case 'D':
        return {0b110, 0b101, 0b101, 0b101, 0b110};
    case 'I':
        return {0b111, 0b010, 0b010, 0b010, 0b111};
    case 'G':
        return {0b011, 0b100, 0b101, 0b101, 0b011};
    default:
        return {0, 0, 0, 0, 0};
    }
}

constexpr int kScale = 2, kRow = 16, kPad = 4, kSwatch = 10;

void fill(Image& im, int x0, int y0, int w, int h, Rgba8 c) {
    for (int y = y0; y < y0 + h; ++y)
        for (int x = x0; x < x0 + w; ++x) im.color[im.index(x, y)] = c;
}

void text(Image& im, int x0, int y0, std::string_view s, Rgba8 c) {
    for (std::size_t k = 0; k < s.size(); ++k) {
        const auto rows = glyph(s[k]);
        for (int r = 0; r < 5; ++r)
            for (int b = 0; b < 3; ++b)
                if (rows[std::size_t(r)] >> (2 - b) & 1)
                    fill(im, x0 + int(k) * 4 * kScale + b * kScale, y0 + r * kScale, kScale, kScale,
                         c);
    }
}

} // namespace

void drawTierLegend(Image& im) {
    constexpr int width = kPad * 3 + kSwatch + 6 * 4 * kScale, height = kPad * 2 + 3 * kRow;
    if (im.width < 96 || im.height < 56) return;
    fill(im, 0, 0, width, height, packRgba(20, 20, 20));
    const std::pair<Rgba8, std::string_view> rows[3] = {
        {kTierTints[0], "NEAR"}, {kTierTints[1], "FAR"}, {tintFading(packRgba(0, 0, 0)), "FADING"}};
    for (int i = 0; i < 3; ++i) {
        const int y = kPad + i * kRow;
        fill(im, kPad, y + 1, kSwatch, kSwatch, rows[i].first);
        text(im, kPad * 2 + kSwatch, y + 1, rows[i].second, packRgba(230, 230, 230));
    }
}

} // namespace voxtier
