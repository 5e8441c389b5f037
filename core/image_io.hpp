#pragma once
// Image files through OpenImageIO (the only place voxtier touches OIIO, DESIGN.md §1).
#include "core/image.hpp"

#include <filesystem>
#include <memory>

namespace voxtier {

/// Writes the colour image; the format follows the extension (.png, .exr, .tif, ...).
/// .exr is float: R, G, B linear (decoded from the 8-bit sRGB colour; tagged oiio:ColorSpace
/// "Linear"; premultiplied by A, as EXR expects), A, then "Z", the view depth in metres of the
/// sprite's model centre (DESIGN.md §3.8: every pixel of a sprite has its centre's depth; +inf
/// where empty; needs the camera's zNear), and "id", the entity id as float (-1 where empty).
/// The file is whole or absent (core/file_write.hpp): encoded in memory, written under a
/// temporary name, renamed. Throws InputError naming the file and the OS reason on failure.
void writeImage(const std::filesystem::path& file, const Image& image, double zNear = 0.0);
/// An animated image (GIF), written one frame at a time: every frame the same size, shown for
/// 1/fps s on average (GIF stores the delay in 1/100 s, so 30 fps alternates 3, 3, 4). InputError
/// naming the file when it cannot be written or a frame's size differs from the first. Nothing
/// reaches the disk before close(), which writes the whole file (core/file_write.hpp); an animation
/// destroyed without close() (a run that failed or was killed part-way) leaves no file.
class AnimationWriter {
  public:
    AnimationWriter(std::filesystem::path file, double fps);
    ~AnimationWriter();
    AnimationWriter(const AnimationWriter&) = delete;
    AnimationWriter& operator=(const AnimationWriter&) = delete;
    void add(const Image& frame);
    /// Finishes and writes the file.
    void close();

  private:
    struct Impl;
    std::unique_ptr<Impl> impl_;
};

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
