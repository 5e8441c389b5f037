#pragma once
// What image_files.cpp needs from the image library behind it: OpenImageIO, loaded on first use
// (image_files/image_library_loader.cpp) or none (image_files/no_image_library.cpp, a build
// configured with VOXTIER_IMAGE_FILES=OFF). Exactly one of the two is linked into a program.
#include "core/image.hpp"

#include <filesystem>
#include <string>

namespace voxtier::detail {

/// True where OpenImageIO is at hand: built with it, and its module loaded (which the first call
/// does).
bool imageLibraryLoaded();
/// Why not, in one line ("" where it is).
std::string imageLibraryFailure();
/// Writes a format other than .pam (the caller has checked that the library is loaded).
/// `colorOnly`: the colour channels alone, also in an EXR (no Z, no id).
void writeWithImageLibrary(const std::filesystem::path& file, const Image& image, double zNear,
                           bool colorOnly);

} // namespace voxtier::detail
