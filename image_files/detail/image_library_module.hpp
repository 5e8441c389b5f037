#pragma once
// The boundary between image_files and its OpenImageIO module (image_files/openimageio_module.cpp,
// built as libvoxtier_openimageio.so and loaded by image_files/image_library_loader.cpp on the
// first write or read of a format that needs it).
//
// Why a module loaded on first use, not a linked library: OpenImageIO pulls ~250 shared libraries
// (OpenCV, GDAL, FFmpeg, ...) into every process that links it, and loading and relocating them
// took 0.58 s of CPU at each start of the CLI, `--help` and a .pam render included
// (docs/decisions/ci-time.md). Only the programs that write a .png, .exr, .tif or .jpg pay it now.
//
// Only standard types cross the boundary, and nothing is thrown across it: the module and
// image_files are built by the same compiler in the same build, but the module links nothing of
// voxtier (no second copy of core's code or state in the process).
#include <cstdint>
#include <string>
#include <vector>

namespace voxtier::detail {

/// One image to encode: `channels` interleaved values a pixel, rows from the top.
struct EncodeRequest {
    int width = 0, height = 0, channels = 0;
    bool floats = false; ///< float values, else 8-bit
    const void* pixels = nullptr;
    std::vector<std::string> channelNames; ///< empty: the format's defaults
    int zChannel = -1, alphaChannel = -1;  ///< -1: none
    std::string colorSpace;                ///< "oiio:ColorSpace", "" for none
};

/// An image read back as 8-bit values, `channels` a pixel.
struct DecodedImage {
    int width = 0, height = 0, channels = 0;
    std::vector<std::uint8_t> pixels;
};

/// The module's functions. Each returns "" on success, else one line saying why
/// ("cannot encode image: ..."); none throws.
struct ImageLibraryModule {
    int abi; ///< kImageLibraryAbi of the build that made the module
    /// Encodes in the format `file`'s extension names, into `bytes` (the file is not touched).
    std::string (*encode)(const std::string& file, const EncodeRequest& request,
                          std::vector<unsigned char>& bytes);
    /// Reads the file's first subimage, converted to 8 bits a channel.
    std::string (*read)(const std::string& file, DecodedImage& image);
};

/// Raised whenever ImageLibraryModule or the two structs change, so that a stale module from
/// another build is refused with a message rather than called with the wrong layout.
inline constexpr int kImageLibraryAbi = 1;
/// The module's one exported symbol: `const ImageLibraryModule* voxtier_image_library_module()`.
inline constexpr const char* kImageLibraryEntry = "voxtier_image_library_module";
/// Its file name, found by image_library_loader.cpp.
inline constexpr const char* kImageLibraryFile = "libvoxtier_openimageio.so";

} // namespace voxtier::detail
