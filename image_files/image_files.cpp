#include "image_files/image_files.hpp"

#include "core/error.hpp"
#include "core/file_write.hpp"
#include "core/sprite_kernel.h"
#include "image_files/detail/image_library.hpp"

#include <cctype>
#include <cstdint>
#include <string>
#include <vector>

namespace voxtier {

std::string lowerExtension(const std::filesystem::path& file) {
    std::string ext = file.extension().string();
    for (char& c : ext) c = char(std::tolower(static_cast<unsigned char>(c)));
    return ext;
}

namespace {

/// Netpbm PAM (P7): a text header, then the RGBA bytes of each row from the top.
void writePam(const std::filesystem::path& file, const Image& img) {
    const std::string header = "P7\nWIDTH " + std::to_string(img.width) + "\nHEIGHT " +
                               std::to_string(img.height) +
                               "\nDEPTH 4\nMAXVAL 255\nTUPLTYPE RGB_ALPHA\nENDHDR\n";
    std::vector<std::uint8_t> bytes(header.begin(), header.end());
    bytes.reserve(header.size() + img.pixelCount() * 4);
    for (std::size_t i = 0; i < img.pixelCount(); ++i)
        for (int c = 0; c < 4; ++c) bytes.push_back(std::uint8_t(channel(img.color[i], c)));
    writeFileWhole(file, bytes);
}

} // namespace

bool imageLibraryAvailable() {
    return detail::imageLibraryLinked();
}

bool canWriteImageFormat(const std::filesystem::path& file) {
    return imageFormatRefusal(file).empty();
}

std::string imageFormatRefusal(const std::filesystem::path& file) {
    const std::string ext = lowerExtension(file);
    if (ext == ".pam" || imageLibraryAvailable()) return "";
    return "cannot write " + (ext.empty() ? std::string("a file without an extension") : ext) +
           ": this voxtier is built without OpenImageIO (VOXTIER_IMAGE_FILES=OFF, the portable "
           "build); write .pam";
}

namespace {

void write(const std::filesystem::path& file, const Image& img, double zNear, bool colorOnly) {
    if (lowerExtension(file) == ".pam") return writePam(file, img);
    const std::string refusal = imageFormatRefusal(file);
    if (!refusal.empty()) throw InputError(file.string(), "", refusal);
    detail::writeWithImageLibrary(file, img, zNear, colorOnly);
}

} // namespace

void writeImage(const std::filesystem::path& file, const Image& img, double zNear) {
    write(file, img, zNear, false);
}

void writeIdImage(const std::filesystem::path& file, const Image& img) {
    Image vis = img;
    for (std::size_t i = 0; i < img.pixelCount(); ++i) {
        if (img.id[i] == kernel::VT_NO_ENTITY) {
            vis.color[i] = packRgba(0, 0, 0);
            continue;
        }
        std::uint32_t h = img.id[i] * 2654435761u;
        h ^= h >> 15;
        vis.color[i] = packRgba(64 + (h & 191), 64 + ((h >> 8) & 191), 64 + ((h >> 16) & 191));
    }
    // The colour-coded ids alone, also in an EXR (no Z or id channels).
    write(file, vis, 0.0, true);
}

} // namespace voxtier
