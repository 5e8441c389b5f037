#pragma once
// The tier overlay's colours and its legend (FrameOptions::overlay, `render --overlay`).
#include "core/image.hpp"

#include <array>

namespace voxtier {

/// Near sprites are tinted blue and far ones orange (each pixel averaged with the tint), so a
/// tinted near pixel has blue >= 127 and a tinted far pixel red >= 127. Cross-fading sprites
/// take green instead: red and blue at most 63, green at least 191 (tintFading), which no tinted
/// near or far pixel, and no black outline, can show.
inline constexpr std::array<Rgba8, 2> kTierTints = {packRgba(60, 140, 255), packRgba(255, 150, 40)};
inline Rgba8 tintFading(Rgba8 c) {
    return packRgba(channel(c, 0) / 4, 191 + channel(c, 1) / 4, channel(c, 2) / 4);
}

/// Draws the legend (a swatch and "NEAR", "FAR", "FADING") into the top-left corner, when the
/// image is at least 96x56 pixels.
void drawTierLegend(Image& overlay);

} // namespace voxtier
