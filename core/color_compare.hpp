#pragma once
// The colour error between two frames, in memory, with no image library (ARCHITECTURE.md: image
// file formats live in image_files/, which the renderer's modules do not use).
#include "core/image.hpp"

namespace voxtier {

/// The colour error of `test` against `truth` (same size), over the four 8-bit channels read as
/// values in [0, 1], with OpenImageIO's ImageBufAlgo::compare definitions: the root-mean-square
/// error per channel value, PSNR = 20 log10(1 / rmse) (+inf for equal images), the largest
/// channel error.
struct ColorCompare {
    double rmse = 0.0, psnr = 0.0, maxError = 0.0;
};
ColorCompare compareColor(const Image& truth, const Image& test);

} // namespace voxtier
