// image_files/: the .pam every build writes (no library: the byte-for-byte check of the portable
// build, tests/portable_test.sh, rests on it), the GIF encoder (exact up to 256 colours a frame,
// decoded here by OpenImageIO, an independent decoder), the id image's colours, and the in-memory
// colour comparison that replaced OpenImageIO's in the error metrics (core/color_compare.hpp).
#include "cli_support.hpp"
#include "core/color_compare.hpp"
#include "core/error.hpp"
#include "core/sprite_kernel.h"
#include "image_files/image_files.hpp"

#include <OpenImageIO/imageio.h>
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <set>
#include <string>
#include <vector>

namespace voxtier {
namespace {

namespace fs = std::filesystem;

std::string readBytes(const fs::path& file) {
    std::ifstream in(file, std::ios::binary);
    return std::string(std::istreambuf_iterator<char>(in), {});
}

Image gradient(int w, int h) {
    Image img(w, h, packRgba(1, 2, 3, 4));
    for (int y = 0; y < h; ++y)
        for (int x = 0; x < w; ++x)
            if ((x + y) % 3 == 0)
                img.writeIfNearer(img.index(x, y), packRgba(x * 40, y * 50, 200, 255), 0.5f,
                                  std::uint32_t(x + 10 * y));
    return img;
}

TEST(ImageFiles, PamIsTheColourPlaneByteForByte) {
    const fs::path dir = test::scratchDir("voxtier_image_files", true);
    const Image img = gradient(5, 3);
    writeImage(dir / "a.PAM", img); // any case
    const std::string header =
        "P7\nWIDTH 5\nHEIGHT 3\nDEPTH 4\nMAXVAL 255\nTUPLTYPE RGB_ALPHA\nENDHDR\n";
    const std::string bytes = readBytes(dir / "a.PAM");
    ASSERT_EQ(bytes.size(), header.size() + 5 * 3 * 4);
    EXPECT_EQ(bytes.substr(0, header.size()), header);
    for (std::size_t i = 0; i < img.pixelCount(); ++i)
        for (int c = 0; c < 4; ++c)
            ASSERT_EQ(std::uint8_t(bytes[header.size() + i * 4 + std::size_t(c)]),
                      channel(img.color[i], c))
                << "pixel " << i << " channel " << c;
}

TEST(ImageFiles, IdImageAsPamColoursEachEntityAndLeavesEmptyBlack) {
    const fs::path dir = test::scratchDir("voxtier_image_files", true);
    const Image img = gradient(4, 4);
    writeIdImage(dir / "ids.pam", img);
    const std::string bytes = readBytes(dir / "ids.pam");
    const std::size_t at = bytes.find("ENDHDR\n") + 7;
    ASSERT_EQ(bytes.size(), at + 4 * 4 * 4);
    for (std::size_t i = 0; i < img.pixelCount(); ++i) {
        const auto px = [&](int c) { return unsigned(std::uint8_t(bytes[at + i * 4 + c])); };
        if (img.id[i] == kernel::VT_NO_ENTITY) {
            EXPECT_EQ(px(0) + px(1) + px(2), 0u) << i;
        } else {
            EXPECT_GE(std::min({px(0), px(1), px(2)}), 64u) << i; // every id a bright colour
        }
        EXPECT_EQ(px(3), 255u);
    }
}

TEST(ImageFiles, ThisBuildWritesEveryFormat) {
    ASSERT_TRUE(imageLibraryAvailable()) << "the test suite is built with VOXTIER_IMAGE_FILES=ON";
    for (const char* f : {"a.png", "a.exr", "a.tif", "a.jpg", "a.gif", "a.pam", "A.PNG"})
        EXPECT_TRUE(canWriteImageFormat(f)) << f;
}

/// Every frame of a GIF as a decoder shows it (OpenImageIO composes the stored rectangles with
/// their transparency and disposal): RGB, packed as Rgba8 with alpha 255.
std::vector<std::vector<Rgba8>> decodeGif(const fs::path& file) {
    std::vector<std::vector<Rgba8>> frames;
    auto in = OIIO::ImageInput::open(file.string());
    EXPECT_TRUE(in) << OIIO::geterror();
    if (!in) return frames;
    for (int k = 0; in->seek_subimage(k, 0); ++k) {
        const OIIO::ImageSpec& spec = in->spec();
        const auto n = std::size_t(spec.width) * std::size_t(spec.height);
        const auto ch = std::size_t(spec.nchannels);
        std::vector<std::uint8_t> px(n * ch);
        EXPECT_TRUE(in->read_image(k, 0, 0, spec.nchannels, OIIO::TypeDesc::UINT8, px.data()));
        std::vector<Rgba8> rgb(n);
        for (std::size_t i = 0; i < n; ++i)
            rgb[i] = packRgba(px[i * ch], px[i * ch + 1], px[i * ch + 2]);
        frames.push_back(std::move(rgb));
    }
    return frames;
}

std::vector<Rgba8> opaque(const Image& img) {
    std::vector<Rgba8> rgb(img.pixelCount());
    for (std::size_t i = 0; i < rgb.size(); ++i) rgb[i] = img.color[i] | 0xFF000000u;
    return rgb;
}

std::size_t colourCount(const Image& img) {
    return std::set<Rgba8>(img.color.begin(), img.color.end()).size();
}

/// 40x30 pixels of exactly 256 colours.
Image allColours() {
    Image img(40, 30, 0);
    for (int y = 0; y < 30; ++y)
        for (int x = 0; x < 40; ++x) {
            const unsigned k = unsigned(x + 40 * y) % 256;
            img.color[img.index(x, y)] = packRgba(k, 255 - k, (k * 7) & 255);
        }
    return img;
}

/// A flat background with a 6x6 square of another colour at (x, y).
Image square(int x0, int y0, Rgba8 background = packRgba(40, 44, 52)) {
    Image img(40, 30, background);
    for (int y = y0; y < y0 + 6; ++y)
        for (int x = x0; x < x0 + 6; ++x) img.color[img.index(x, y)] = packRgba(200, 30, 90);
    return img;
}

// A GIF of frames of at most 256 colours decodes to every frame's pixels exactly: the first of
// 256 colours, a square moving over a flat background (each later frame stores only what
// changed), a frame like the one before, and a frame whose changes need all 256 colours again.
TEST(ImageFiles, GifOfAtMost256ColoursDecodesExactlyFrameByFrame) {
    const fs::path dir = test::scratchDir("voxtier_image_files", true);
    std::vector<Image> frames = {allColours(),  square(2, 3), square(5, 3),  square(5, 3),
                                 square(9, 12), allColours(), square(30, 20)};
    ASSERT_EQ(colourCount(frames[0]), 256u);
    AnimationWriter gif(dir / "a.gif", 10.0);
    for (const Image& f : frames) gif.add(f);
    gif.close();
    EXPECT_EQ(gif.fidelity().frames, frames.size());
    EXPECT_EQ(gif.fidelity().approximated, 0u);
    EXPECT_EQ(gifFidelityNote(dir / "a.gif", gif.fidelity()), "");
    const auto decoded = decodeGif(dir / "a.gif");
    ASSERT_EQ(decoded.size(), frames.size());
    for (std::size_t k = 0; k < frames.size(); ++k)
        EXPECT_TRUE(decoded[k] == opaque(frames[k])) << "frame " << k;
    // A still GIF through writeImage, too.
    writeImage(dir / "still.gif", frames[0]);
    const auto still = decodeGif(dir / "still.gif");
    ASSERT_EQ(still.size(), 1u);
    EXPECT_TRUE(still[0] == opaque(frames[0]));
}

// A frame of more colours than 256 is drawn in 256 of them without dithering (pixels of one
// colour stay one colour), the writer counts it, and the frames after it are exact again: no
// approximated pixel of it is left standing where they differ.
TEST(ImageFiles, GifOfMoreColoursIsApproximatedWithoutDitheringAndLeavesNoStalePixel) {
    const fs::path dir = test::scratchDir("voxtier_image_files", true);
    Image bands(40, 30 * 20, 0); // 600 rows, each its own colour
    for (int y = 0; y < bands.height; ++y)
        for (int x = 0; x < bands.width; ++x)
            bands.color[bands.index(x, y)] = packRgba(unsigned(y) & 255, unsigned(y >> 8) * 90, 50);
    ASSERT_EQ(colourCount(bands), 600u);
    // The next frame keeps the first 200 rows of the bands (202 colours in all): a decoder that
    // shows them approximated, as the first frame left them, would show a stale pixel.
    Image half = bands;
    for (int y = 200; y < 600; ++y)
        for (int x = 0; x < 40; ++x)
            half.color[half.index(x, y)] = x < 20 ? packRgba(0, 0, 0) : packRgba(255, 255, 255);
    ASSERT_EQ(colourCount(half), 202u);
    Image moved = half;
    for (int y = 100; y < 110; ++y)
        for (int x = 15; x < 25; ++x) moved.color[moved.index(x, y)] = packRgba(200, 30, 90);
    AnimationWriter gif(dir / "b.gif", 10.0);
    for (const Image* f : {&bands, &half, &moved}) gif.add(*f);
    gif.close();
    EXPECT_EQ(gif.fidelity().frames, 3u);
    EXPECT_EQ(gif.fidelity().approximated, 1u);
    EXPECT_EQ(gif.fidelity().mostColours, 600u);
    const auto decoded = decodeGif(dir / "b.gif");
    ASSERT_EQ(decoded.size(), 3u);
    std::set<Rgba8> used;
    for (int y = 0; y < bands.height; ++y) {
        const Rgba8 row = decoded[0][bands.index(0, y)];
        used.insert(row);
        for (int x = 1; x < bands.width; ++x)
            ASSERT_EQ(decoded[0][bands.index(x, y)], row) << "dithered at " << x << "," << y;
        // The nearest of 256 colours spread over 600 rows is never far from the row's own.
        const Rgba8 want = bands.color[bands.index(0, y)];
        for (int c = 0; c < 3; ++c)
            EXPECT_LE(std::abs(int(channel(row, c)) - int(channel(want, c))), 8) << "row " << y;
    }
    EXPECT_LE(used.size(), 256u);
    EXPECT_TRUE(decoded[1] == opaque(half)) << "a pixel of the approximated frame was left";
    EXPECT_TRUE(decoded[2] == opaque(moved));
}

TEST(ImageFiles, GifFidelityNoteCountsFramesAndNamesLosslessFormats) {
    GifFidelity f;
    f.frames = 151;
    f.approximated = 109;
    f.mostColours = 455;
    EXPECT_EQ(gifFidelityNote("out/a.gif", f),
              "out/a.gif: 109 of 151 frames have more colours than GIF's 256 a frame (up to "
              "455), so those are drawn in the nearest of 256 colours (no dithering); for exact "
              "pixels write .png (a sequence: numbered PNGs) or .pam");
    f.frames = f.approximated = 1;
    EXPECT_NE(gifFidelityNote("a.gif", f).find("a.gif: the image has more colours"),
              std::string::npos);
}

// Every entity a scene may hold has its own colour in the id image, every channel bright, so a
// colour names one entity and none is black (no entity).
TEST(ImageFiles, IdColoursAreDistinctAndBrightForEveryEntityASceneMayHold) {
    std::vector<std::uint32_t> seen(std::size_t(1) << 24 >> 5);
    for (std::uint32_t id = 0; id < 1000000; ++id) {
        const Rgba8 c = idColor(id) & 0xFFFFFFu;
        ASSERT_GE(std::min({channel(c, 0), channel(c, 1), channel(c, 2)}), 64u) << id;
        ASSERT_FALSE(seen[c >> 5] >> (c & 31) & 1) << "id " << id << " repeats a colour";
        seen[c >> 5] |= 1u << (c & 31);
    }
    EXPECT_NE(idColor(0), idColor(1));
}

TEST(ColorCompare, EqualImagesHaveZeroErrorAndInfinitePsnr) {
    const Image a = gradient(7, 5);
    const ColorCompare c = compareColor(a, a);
    EXPECT_EQ(c.rmse, 0.0);
    EXPECT_EQ(c.maxError, 0.0);
    EXPECT_TRUE(std::isinf(c.psnr) && c.psnr > 0);
}

TEST(ColorCompare, OneChannelOffByDIsTheClosedForm) {
    // 10x10 pixels, 4 channels: one channel of one pixel off by 51 (0.2): the mean squared
    // error per channel value is 0.04 / 400, rmse 0.01, PSNR 40 dB.
    Image a(10, 10, packRgba(100, 100, 100, 255)), b = a;
    b.color[37] = packRgba(151, 100, 100, 255);
    const ColorCompare c = compareColor(a, b);
    EXPECT_NEAR(c.rmse, 0.01, 1e-12);
    EXPECT_NEAR(c.psnr, 40.0, 1e-9);
    EXPECT_NEAR(c.maxError, 0.2, 1e-12);
    EXPECT_EQ(compareColor(b, a).rmse, c.rmse) << "symmetric";
}

} // namespace
} // namespace voxtier
