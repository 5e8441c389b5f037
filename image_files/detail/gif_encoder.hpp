#pragma once
// A GIF89a encoder with no library (image_files/gif_encoder.cpp), so that a GIF holds exactly the
// pixels it was given wherever the format can: GIF has at most 256 colours per frame, and an image
// library's GIF writer (OpenImageIO's, through giflib) picks one palette by a fixed quantiser and
// dithers, which smears the pixel-art sprites even where the frame has fewer colours.
//
// The contract:
// - Each frame gets its own palette (a local colour table), chosen from its own colours: a frame
//   whose pixels to draw have at most 256 colours (255 when the frame leaves unchanged pixels
//   transparent, see below) decodes to exactly those colours. A frame with more is reduced by a
//   median cut to that many, each pixel drawn in the palette colour nearest its own; no
//   dithering, so a flat region stays flat.
// - Every frame after the first stores only the rectangle around the pixels that differ from what
//   a decoder shows at that moment (its canvas, with the approximations of earlier frames
//   included), with the pixels inside it that already show the right colour left transparent
//   (disposal "do not dispose"). So no pixel of an earlier frame is left standing where the new
//   frame differs from it: a decoder shows each frame's given pixels, or their nearest palette
//   colour in a frame that had too many colours.
// - Alpha is not stored (GIF has 1-bit transparency at best, and that bit is used above): each
//   pixel's colour channels are.
#include "core/image.hpp"

#include <cstddef>
#include <cstdint>
#include <vector>

namespace voxtier::detail {

/// How exactly one encoded frame holds the image it was given.
struct GifFrameFidelity {
    bool exact = true; ///< the decoded frame shows every given pixel's colour
    /// Distinct colours of the frame; counted only where it is not exact (else 0).
    std::size_t colours = 0;
};

class GifEncoder {
  public:
    /// An image of width x height pixels (both in 1..65535). `animation`: the file loops forever
    /// and every frame carries its delay; else one still image.
    GifEncoder(int width, int height, bool animation);
    /// Appends one frame, of the encoder's size, shown for `delayCs` (in 0..65535) hundredths of
    /// a second.
    GifFrameFidelity add(const Image& frame, int delayCs);
    /// The file's bytes, the trailer included. Call once, after the last add().
    std::vector<std::uint8_t> finish();

  private:
    int width_, height_;
    bool animation_;
    std::size_t frames_ = 0;
    std::vector<std::uint8_t> body_;    ///< the frames' blocks
    std::vector<std::uint32_t> canvas_; ///< what a decoder shows after the last frame (RGB)
};

} // namespace voxtier::detail
