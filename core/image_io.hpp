#pragma once
// Image files through OpenImageIO (the only place voxtier touches OIIO, DESIGN.md §1).
#include "core/image.hpp"

#include <filesystem>

namespace voxtier {

/// Writes the colour image; the format follows the extension (.png, .exr, .tif, ...).
/// For .exr the file also carries channel "Z" (view depth in metres, +inf where empty; needs
/// the camera's zNear) and "id" (entity id as float, -1 where empty). Throws InputError on
/// failure, naming the file.
void writeImage(const std::filesystem::path& file, const Image& image, double zNear = 0.0);
/// The entity-id buffer as a colour-coded PNG (each id a stable pseudo-random colour).
void writeIdImage(const std::filesystem::path& file, const Image& image);
/// Reads an 8-bit RGBA image (depth and id left empty).
Image readColorImage(const std::filesystem::path& file);

/// OIIO's ImageBufAlgo::compare on the colour channels (values in [0, 1]).
struct ColorCompare {
    double rmse = 0.0, psnr = 0.0, maxError = 0.0;
    std::size_t pixelsOverThreshold = 0;
};
ColorCompare compareColor(const Image& a, const Image& b, float threshold = 1.0f / 255.0f);

} // namespace voxtier
