// The formats that need an image library, through OpenImageIO: the only file of voxtier that
// includes it (DESIGN.md §1). Linked where VOXTIER_IMAGE_FILES=ON.
#include "core/error.hpp"
#include "core/file_write.hpp"
#include "core/sprite_kernel.h"
#include "image_files/detail/image_library.hpp"
#include "image_files/image_files.hpp"

#include <OpenImageIO/filesystem.h>
#include <OpenImageIO/imagebuf.h>
#include <OpenImageIO/imageio.h>

#include <algorithm>
#include <cmath>
#include <limits>

namespace voxtier {

namespace {

/// The sRGB transfer function's inverse (IEC 61966-2-1): 8-bit sRGB code -> linear [0, 1].
float linearFromSrgb8(unsigned code) {
    const double c = double(code) / 255.0;
    return float(c <= 0.04045 ? c / 12.92 : std::pow((c + 0.055) / 1.055, 2.4));
}

/// An ImageOutput for `file`'s format that writes into `proxy` (memory) instead of the file, so
/// that the bytes reach the disk only through writeFileWhole, which checks every OS result.
std::unique_ptr<OIIO::ImageOutput> memoryOutput(const std::string& file,
                                                OIIO::Filesystem::IOProxy* proxy) {
    std::unique_ptr<OIIO::ImageOutput> out = OIIO::ImageOutput::create(file);
    if (!out) throw InputError(file, "", "cannot write image: " + OIIO::geterror());
    if (!out->supports("ioproxy") || !out->set_ioproxy(proxy))
        throw InputError(file, "", "cannot write an image in this format");
    return out;
}

/// Encodes the pixels in `file`'s format, then writes the file whole or not at all.
void writeEncoded(const std::filesystem::path& file, const OIIO::ImageSpec& spec,
                  OIIO::TypeDesc type, const void* pixels) {
    const std::string name = file.string();
    std::vector<unsigned char> bytes;
    OIIO::Filesystem::IOVecOutput proxy(bytes);
    const std::unique_ptr<OIIO::ImageOutput> out = memoryOutput(name, &proxy);
    const bool ok = out->open(name, spec) && out->write_image(type, pixels);
    // close() also flushes the encoder's last bytes: its result counts like a write's.
    if (!out->close() || !ok) throw InputError(name, "", "cannot encode image: " + out->geterror());
    writeFileWhole(file, bytes);
}

void writeColor(const std::filesystem::path& file, const Image& img) {
    writeEncoded(file, OIIO::ImageSpec(img.width, img.height, 4, OIIO::TypeDesc::UINT8),
                 OIIO::TypeDesc::UINT8, img.color.data());
}

} // namespace

namespace detail {

bool imageLibraryLinked() {
    return true;
}

void writeWithImageLibrary(const std::filesystem::path& file, const Image& img, double zNear,
                           bool colorOnly) {
    if (lowerExtension(file) != ".exr" || colorOnly) {
        writeColor(file, img);
        return;
    }
    // EXR: RGB decoded from the 8-bit sRGB colour to linear (EXR's convention, what
    // compositors assume) and premultiplied by alpha, + Z (view depth) + id.
    OIIO::ImageSpec spec(img.width, img.height, 6, OIIO::TypeDesc::FLOAT);
    spec.channelnames = {"R", "G", "B", "A", "Z", "id"};
    spec.z_channel = 4;
    spec.alpha_channel = 3;
    spec.attribute("oiio:ColorSpace", "Linear");
    std::vector<float> px(img.pixelCount() * 6);
    for (std::size_t i = 0; i < img.pixelCount(); ++i) {
        // EXR colour is premultiplied by alpha (associated), unlike PNG's.
        const float alpha = float(channel(img.color[i], 3)) / 255.0f;
        for (int c = 0; c < 3; ++c)
            px[i * 6 + std::size_t(c)] = linearFromSrgb8(channel(img.color[i], c)) * alpha;
        px[i * 6 + 3] = alpha;
        const float d = img.depth[i];
        px[i * 6 + 4] =
            (d > 0.0f && zNear > 0.0) ? float(zNear / d) : std::numeric_limits<float>::infinity();
        px[i * 6 + 5] = img.id[i] == kernel::VT_NO_ENTITY ? -1.0f : float(img.id[i]);
    }
    writeEncoded(file, spec, OIIO::TypeDesc::FLOAT, px.data());
}

} // namespace detail

Image readColorImage(const std::filesystem::path& file) {
    OIIO::ImageBuf buf(file.string());
    if (!buf.read(0, 0, true, OIIO::TypeDesc::UINT8))
        throw InputError(file.string(), "", "cannot read image: " + buf.geterror());
    const OIIO::ImageSpec& spec = buf.spec();
    Image img(spec.width, spec.height, 0);
    std::vector<std::uint8_t> px(img.pixelCount() * std::size_t(spec.nchannels));
    buf.get_pixels(OIIO::ROI::All(), OIIO::TypeDesc::UINT8, px.data());
    for (std::size_t i = 0; i < img.pixelCount(); ++i) {
        unsigned ch[4] = {0, 0, 0, 255};
        for (int c = 0; c < std::min(4, spec.nchannels); ++c)
            ch[c] = px[i * std::size_t(spec.nchannels) + std::size_t(c)];
        if (spec.nchannels < 3) ch[1] = ch[2] = ch[0];
        img.color[i] = packRgba(ch[0], ch[1], ch[2], ch[3]);
    }
    return img;
}

} // namespace voxtier
