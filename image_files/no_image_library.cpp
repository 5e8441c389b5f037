// A build without OpenImageIO (VOXTIER_IMAGE_FILES=OFF, tools/portable.sh): .pam and .gif are
// written by image_files.cpp; every format that needs the library is refused with one InputError
// line.
#include "core/error.hpp"
#include "image_files/detail/image_library.hpp"
#include "image_files/image_files.hpp"

namespace voxtier {

namespace detail {

bool imageLibraryLoaded() {
    return false;
}

std::string imageLibraryFailure() {
    return "this voxtier is built without OpenImageIO (VOXTIER_IMAGE_FILES=OFF, the portable "
           "build)";
}

void writeWithImageLibrary(const std::filesystem::path& file, const Image&, double, bool) {
    throw InputError(file.string(), "", imageFormatRefusal(file));
}

} // namespace detail

Image readColorImage(const std::filesystem::path& file) {
    throw InputError(file.string(), "",
                     "cannot read an image: this voxtier is built without OpenImageIO "
                     "(VOXTIER_IMAGE_FILES=OFF)");
}

} // namespace voxtier
