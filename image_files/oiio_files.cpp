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

struct AnimationWriter::Impl {
    std::filesystem::path file;
    double fps = 30.0;
    /// The frames are encoded into memory and reach the disk whole at close(): a run killed or
    /// failing part-way leaves no shorter GIF that looks complete.
    std::vector<unsigned char> bytes;
    OIIO::Filesystem::IOVecOutput proxy{bytes};
    std::unique_ptr<OIIO::ImageOutput> out;
    int width = 0, height = 0;
    bool open = false;
};

namespace {

/// The GIF delay of frame `k` (1/100 s): frame k starts at round(100 k / fps) centiseconds, so
/// that the delays sum to the path's duration and the average frame rate is fps (30 fps:
/// 3, 3, 4, 3, 3, 4 ...) instead of 100 / round(100 / fps) (33.3 fps at 30).
int gifDelay(double fps, int k) {
    const auto start = [fps](int i) { return std::llround(100.0 * double(i) / fps); };
    return int(std::clamp<long long>(start(k + 1) - start(k), 1, 65535));
}

/// Sets the delay of the k-th frame of the GIF in `gif` to gifDelay(fps, k). OIIO 2.4's GIF
/// writer takes one delay for the whole file (from the first frame's FramesPerSecond), so the
/// delays are rewritten in the encoded bytes: each frame's Graphic Control Extension (GIF89a
/// spec section 23) holds it in bytes 4-5. The walk follows the block structure (section 18 on),
/// so image data that happens to hold the extension's bytes is never touched. Returns false if
/// the bytes are not the GIF structure expected.
bool spreadGifDelays(std::vector<unsigned char>& gif, double fps) {
    const std::size_t n = gif.size();
    const auto colorTable = [&](std::size_t flagsAt) {
        return (gif[flagsAt] & 0x80) ? std::size_t(3) << ((gif[flagsAt] & 7) + 1) : 0;
    };
    const auto skipSubBlocks = [&](std::size_t at) {
        while (at < n && gif[at] != 0) at += std::size_t(gif[at]) + 1;
        return at + 1; // past the terminator
    };
    if (n < 13) return false;
    std::size_t at = 13 + colorTable(10);
    int frame = 0;
    while (at < n) {
        if (gif[at] == 0x3B) return true; // trailer
        if (gif[at] == 0x21 && at + 1 < n) {
            if (gif[at + 1] == 0xF9 && at + 7 < n && gif[at + 2] == 4) {
                const int d = gifDelay(fps, frame++);
                gif[at + 4] = static_cast<unsigned char>(d & 0xFF);
                gif[at + 5] = static_cast<unsigned char>(d >> 8);
            }
            at = skipSubBlocks(at + 2);
        } else if (gif[at] == 0x2C && at + 10 < n) {
            at += 10 + colorTable(at + 9);
            at = skipSubBlocks(at + 1); // past the LZW minimum code size
        } else {
            return false;
        }
    }
    return false;
}

} // namespace

AnimationWriter::AnimationWriter(std::filesystem::path file, double fps)
    : impl_(std::make_unique<Impl>()) {
    impl_->file = std::move(file);
    impl_->fps = fps;
}

AnimationWriter::~AnimationWriter() = default;

void AnimationWriter::add(const Image& img) {
    Impl& m = *impl_;
    const std::string name = m.file.string();
    OIIO::ImageSpec spec(img.width, img.height, 4, OIIO::TypeDesc::UINT8);
    // OIIO's GIF writer takes the frame delay from FramesPerSecond (a rational); close()
    // spreads the delays (spreadGifDelays).
    const int fpsNum = int(std::lround(m.fps * 1000.0));
    const int rational[2] = {fpsNum, 1000};
    spec.attribute("FramesPerSecond", OIIO::TypeRational, rational);
    spec.attribute("oiio:Movie", 1);
    spec.attribute("gif:LoopCount", 0); // loop forever
    if (!m.open) {
        m.out = memoryOutput(name, &m.proxy);
        if (!m.out->supports("appendsubimage"))
            throw InputError(name, "", "cannot write an animation in this format (use .gif)");
        if (!m.out->open(name, spec, OIIO::ImageOutput::Create))
            throw InputError(name, "", "cannot encode image: " + m.out->geterror());
        m.width = img.width, m.height = img.height, m.open = true;
    } else {
        if (img.width != m.width || img.height != m.height)
            throw InputError(name, "", "animation frames must all be the same size");
        if (!m.out->open(name, spec, OIIO::ImageOutput::AppendSubimage))
            throw InputError(name, "", "cannot encode image: " + m.out->geterror());
    }
    if (!m.out->write_image(OIIO::TypeDesc::UINT8, img.color.data()))
        throw InputError(name, "", "cannot encode image: " + m.out->geterror());
}

void AnimationWriter::close() {
    Impl& m = *impl_;
    if (!m.out) return;
    const bool ok = m.out->close();
    const std::string err = ok ? "" : m.out->geterror();
    m.out.reset();
    if (!ok) throw InputError(m.file.string(), "", "cannot encode image: " + err);
    if (!spreadGifDelays(m.bytes, m.fps))
        throw InputError(m.file.string(), "",
                         "cannot set the GIF frame delays: unexpected encoding");
    writeFileWhole(m.file, m.bytes);
}

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
