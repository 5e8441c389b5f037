#pragma once
// A tiny built-in 5x7 bitmap font for labelling debug images (contact sheets), so nothing
// depends on system fonts. Covers digits, upper-case letters (lower case is drawn as upper
// case) and + - , . ( ) : = / x and space; other characters draw as a hollow box.
#include "core/image.hpp"

#include <string_view>

namespace voxtier {

inline constexpr int kGlyphWidth = 5, kGlyphHeight = 7, kGlyphAdvance = 6;

/// Draws `text` with its top-left corner at (x, y), each font pixel `scale` x `scale` image
/// pixels; clipped to the image. Colour only (depth and id untouched).
void drawText(Image& image, int x, int y, std::string_view text, Rgba8 color, int scale = 1);
/// Width in pixels of `text` at `scale`.
int textWidth(std::string_view text, int scale = 1);

} // namespace voxtier
