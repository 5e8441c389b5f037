// The formats that need an image library, through OpenImageIO: the only file of voxtier that
// includes it (ARCHITECTURE.md). Built as its own shared module, libvoxtier_openimageio.so, and
// loaded on first use (image_files/detail/image_library_module.hpp says why); it encodes to and
// decodes from memory and the file system reads only, so every write still goes through
// core/file_write.hpp on the other side.
#include "image_files/detail/image_library_module.hpp"

#include <OpenImageIO/filesystem.h>
#include <OpenImageIO/imagebuf.h>
#include <OpenImageIO/imageio.h>

#include <exception>
#include <memory>

namespace {

using voxtier::detail::DecodedImage;
using voxtier::detail::EncodeRequest;

/// Encodes the pixels in `file`'s format into `bytes` through an ImageOutput writing to memory,
/// so that the bytes reach the disk only through writeFileWhole, which checks every OS result.
std::string encodeOrWhy(const std::string& file, const EncodeRequest& r,
                        std::vector<unsigned char>& bytes) {
    const OIIO::TypeDesc type = r.floats ? OIIO::TypeDesc::FLOAT : OIIO::TypeDesc::UINT8;
    OIIO::ImageSpec spec(r.width, r.height, r.channels, type);
    if (!r.channelNames.empty()) spec.channelnames = r.channelNames;
    spec.z_channel = r.zChannel;
    spec.alpha_channel = r.alphaChannel;
    if (!r.colorSpace.empty()) spec.attribute("oiio:ColorSpace", r.colorSpace);
    OIIO::Filesystem::IOVecOutput proxy(bytes);
    const std::unique_ptr<OIIO::ImageOutput> out = OIIO::ImageOutput::create(file);
    if (!out) return "cannot write image: " + OIIO::geterror();
    if (!out->supports("ioproxy") || !out->set_ioproxy(&proxy))
        return "cannot write an image in this format";
    const bool ok = out->open(file, spec) && out->write_image(type, r.pixels);
    // close() also flushes the encoder's last bytes: its result counts like a write's.
    if (!out->close() || !ok) return "cannot encode image: " + out->geterror();
    return "";
}

std::string encode(const std::string& file, const EncodeRequest& request,
                   std::vector<unsigned char>& bytes) {
    try {
        return encodeOrWhy(file, request, bytes);
    } catch (const std::exception& e) {
        return std::string("cannot encode image: ") + e.what();
    }
}

std::string read(const std::string& file, DecodedImage& image) {
    try {
        OIIO::ImageBuf buf(file);
        // Decoded and copied out on this thread. OpenImageIO's pool copies a large image's rows
        // on its own threads and hands them back in a way ThreadSanitizer cannot see (the library
        // is uninstrumented): every byte read afterwards was a race, suppressed by tools/tsan.supp
        // only after TSan compared it with each address it had suppressed before, so the
        // shared-cache test's first read of its 960x540 frames was still in TSan's
        // FindRacyAddress after 300 s (with this: the test's round in 57 s). No command reads
        // images; the tests and the library's users do.
        buf.threads(1);
        if (!buf.read(0, 0, true, OIIO::TypeDesc::UINT8))
            return "cannot read image: " + buf.geterror();
        const OIIO::ImageSpec& spec = buf.spec();
        image.width = spec.width;
        image.height = spec.height;
        image.channels = spec.nchannels;
        image.pixels.resize(std::size_t(spec.width) * std::size_t(spec.height) *
                            std::size_t(spec.nchannels));
        if (!buf.get_pixels(OIIO::ROI::All(), OIIO::TypeDesc::UINT8, image.pixels.data()))
            return "cannot read image: " + buf.geterror();
        return "";
    } catch (const std::exception& e) {
        return std::string("cannot read image: ") + e.what();
    }
}

const voxtier::detail::ImageLibraryModule kModule{voxtier::detail::kImageLibraryAbi, encode, read};

} // namespace

extern "C" __attribute__((visibility("default"))) const voxtier::detail::ImageLibraryModule*
voxtier_image_library_module() {
    return &kModule;
}
