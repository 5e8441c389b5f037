#pragma once
// Image files (ARCHITECTURE.md): the one module that writes and reads them. The renderer's modules
// (core to compose) never touch a file format; apps and tests call this module.
//
// Two kinds of format:
// - .pam (Netpbm's PAM, 8-bit RGBA, no compression) and .gif are written here with no library at
//   all, so that every build of voxtier, the portable one included (tools/portable.sh), can
//   write an image and two builds' renders can be compared byte for byte. GIF has its own encoder
//   (image_files/detail/gif_encoder.hpp) because an image library's dithers: this one holds a
//   frame of up to 256 colours exactly.
// - Every other format (.png, .exr, .tif, .jpg) goes through OpenImageIO, in a module of its own
//   (libvoxtier_openimageio.so, image_files/openimageio_module.cpp, the only file that includes
//   it) that the first write or read of such a format loads: a program that writes none of them
//   never loads OpenImageIO's ~250 libraries (image_files/detail/image_library_module.hpp). A build
//   configured with VOXTIER_IMAGE_FILES=OFF has no OpenImageIO: there those formats are refused
//   with one InputError line naming the file, before anything is rendered where the CLI can tell;
//   so are they where the module cannot be loaded, with the loader's reason.
#include "core/image.hpp"

#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <memory>
#include <string>

namespace voxtier {

/// Whether this build writes and reads the formats that need OpenImageIO (the CMake option
/// VOXTIER_IMAGE_FILES, and its module loaded: the first call loads it). .pam is written either
/// way.
bool imageLibraryAvailable();
/// `file`'s extension in lower case (".png"), by which every format here is chosen.
std::string lowerExtension(const std::filesystem::path& file);
/// Whether `file`'s extension (any case) names a format this build writes: .pam and .gif always,
/// .png, .exr, .tif and .jpg where imageLibraryAvailable().
bool canWriteImageFormat(const std::filesystem::path& file);
/// The one-line reason a file of this format cannot be written by this build ("" where it can).
std::string imageFormatRefusal(const std::filesystem::path& file);

/// Writes the colour image; the format follows the extension (.pam, .png, .exr, .tif, ...).
/// .pam is P7 with TUPLTYPE RGB_ALPHA, MAXVAL 255: the colour plane's bytes exactly, row by row
/// from the top (no library; identical bytes from every build).
/// .gif holds the colour channels exactly where the image has at most 256 colours, else their
/// nearest of 256 (gif_encoder.hpp; AnimationWriter says which).
/// .exr is float: R, G, B linear (decoded from the 8-bit sRGB colour; tagged oiio:ColorSpace
/// "Linear"; premultiplied by A, as EXR expects), A, then "Z", the view depth in metres of the
/// sprite's model centre (CONTRACT.md §3.8: every pixel of a sprite has its centre's depth; +inf
/// where empty; needs the camera's zNear), and "id", the entity id as float (-1 where empty).
/// The file is whole or absent (core/file_write.hpp): encoded in memory, written under a
/// temporary name, renamed. Throws InputError naming the file and the OS reason on failure, or
/// imageFormatRefusal when this build cannot write the format.
void writeImage(const std::filesystem::path& file, const Image& image, double zNear = 0.0);
/// What a GIF could not hold exactly: GIF has at most 256 colours per frame.
struct GifFidelity {
    std::size_t frames = 0;       ///< frames written
    std::size_t approximated = 0; ///< of them, frames drawn in the nearest of 256 colours
    std::size_t mostColours = 0;  ///< the most distinct colours of an approximated frame
};
/// The one line that says which frames of `file` are approximated and names a lossless format
/// ("" where every frame is exact).
std::string gifFidelityNote(const std::filesystem::path& file, const GifFidelity& f);

/// An animated image (GIF), written one frame at a time: every frame the same size, shown for
/// 1/fps s on average (GIF stores the delay in 1/100 s, so 30 fps alternates 3, 3, 4). A frame
/// whose pixels have at most 256 colours decodes to exactly those pixels, whatever came before it
/// (image_files/detail/gif_encoder.hpp); fidelity() counts the others. One frame makes a still
/// GIF. InputError naming the file when it cannot be written or a frame's size differs from the
/// first. Nothing reaches the disk before close(), which writes the whole file
/// (core/file_write.hpp); an animation destroyed without close() (a run that failed or was killed
/// part-way) leaves no file. Needs no image library.
class AnimationWriter {
  public:
    AnimationWriter(std::filesystem::path file, double fps);
    ~AnimationWriter();
    AnimationWriter(const AnimationWriter&) = delete;
    AnimationWriter& operator=(const AnimationWriter&) = delete;
    void add(const Image& frame);
    /// Finishes and writes the file.
    void close();
    const GifFidelity& fidelity() const;

  private:
    struct Impl;
    std::unique_ptr<Impl> impl_;
};

/// The colour of entity `id` in an id image: one of 191^3 bright colours (each channel in
/// 64..254), a different one for each id below 191^3 = 6,967,871 (more than a scene may hold), so
/// that a colour names one entity; neighbouring ids get unlike colours. Black is no entity.
Rgba8 idColor(std::uint32_t id);
/// The entity-id buffer as a colour-coded image (idColor; black where empty), in any format
/// writeImage writes (a GIF holds up to 256 of them exactly).
void writeIdImage(const std::filesystem::path& file, const Image& image);
/// Reads an 8-bit RGBA image (depth and id left empty). Needs imageLibraryAvailable().
Image readColorImage(const std::filesystem::path& file);

} // namespace voxtier
