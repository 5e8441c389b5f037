// image_files/: the .pam every build writes (no library: the byte-for-byte check of the portable
// build, tests/portable_test.sh, rests on it) and the in-memory colour comparison that replaced
// OpenImageIO's in the error metrics (core/color_compare.hpp).
#include "cli_support.hpp"
#include "core/color_compare.hpp"
#include "core/error.hpp"
#include "core/sprite_kernel.h"
#include "image_files/image_files.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>

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
