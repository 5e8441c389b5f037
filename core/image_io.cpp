#include "core/image_io.hpp"

#include "core/error.hpp"
#include "core/sprite_kernel.h"

#include <OpenImageIO/imagebuf.h>
#include <OpenImageIO/imagebufalgo.h>
#include <OpenImageIO/imageio.h>

#include <cmath>
#include <limits>

namespace voxtier {

namespace {

OIIO::ImageBuf colorBuf(const Image& img) {
    OIIO::ImageSpec spec(img.width, img.height, 4, OIIO::TypeDesc::UINT8);
    OIIO::ImageBuf buf(spec);
    buf.set_pixels(OIIO::ROI::All(), OIIO::TypeDesc::UINT8, img.color.data());
    return buf;
}

void writeBuf(const std::filesystem::path& file, const OIIO::ImageBuf& buf) {
    if (file.has_parent_path()) std::filesystem::create_directories(file.parent_path());
    if (!buf.write(file.string()))
        throw InputError(file.string(), "", "cannot write image: " + buf.geterror());
}

} // namespace

void writeImage(const std::filesystem::path& file, const Image& img, double zNear) {
    std::string ext = file.extension().string();
    for (char& c : ext) c = char(std::tolower(c));
    if (ext != ".exr") {
        writeBuf(file, colorBuf(img));
        return;
    }
    // EXR: linear float RGBA + Z (view depth) + id.
    OIIO::ImageSpec spec(img.width, img.height, 6, OIIO::TypeDesc::FLOAT);
    spec.channelnames = {"R", "G", "B", "A", "Z", "id"};
    spec.z_channel = 4;
    std::vector<float> px(img.pixelCount() * 6);
    for (std::size_t i = 0; i < img.pixelCount(); ++i) {
        for (int c = 0; c < 4; ++c)
            px[i * 6 + std::size_t(c)] = float(channel(img.color[i], c)) / 255.0f;
        const float d = img.depth[i];
        px[i * 6 + 4] =
            (d > 0.0f && zNear > 0.0) ? float(zNear / d) : std::numeric_limits<float>::infinity();
        px[i * 6 + 5] = img.id[i] == kernel::VT_NO_ENTITY ? -1.0f : float(img.id[i]);
    }
    OIIO::ImageBuf buf(spec);
    buf.set_pixels(OIIO::ROI::All(), OIIO::TypeDesc::FLOAT, px.data());
    writeBuf(file, buf);
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
    writeBuf(file, colorBuf(vis));
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

ColorCompare compareColor(const Image& a, const Image& b, float threshold) {
    const OIIO::ImageBuf A = colorBuf(a), B = colorBuf(b);
    const auto r = OIIO::ImageBufAlgo::compare(A, B, threshold, threshold);
    ColorCompare out;
    out.rmse = r.rms_error;
    out.psnr = r.PSNR;
    out.maxError = r.maxerror;
    out.pixelsOverThreshold = std::size_t(r.nfail + r.nwarn);
    return out;
}

} // namespace voxtier
