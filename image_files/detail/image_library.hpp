#pragma once
// What image_files.cpp needs from the image library behind it: OpenImageIO
// (image_files/oiio_files.cpp) or none (image_files/no_image_library.cpp, a build configured with
// VOXTIER_IMAGE_FILES=OFF). Exactly one of the two is linked into a program.
#include "core/image.hpp"

#include <filesystem>

namespace voxtier::detail {

/// True where OpenImageIO is linked.
bool imageLibraryLinked();
/// Writes a format other than .pam (the caller has checked that the library is linked).
/// `colorOnly`: the colour channels alone, also in an EXR (no Z, no id).
void writeWithImageLibrary(const std::filesystem::path& file, const Image& image, double zNear,
                           bool colorOnly);

} // namespace voxtier::detail
