// What `voxtier render` writes and which frames it renders (issue 14): the camera rule, frame
// ranges, animated GIFs, EXR colour, transparency and the CLI's messages, end to end.
#include "cli_support.hpp"
#include "compose/frame.hpp"
#include "core/model_view.hpp"
#include "core/scene_loader.hpp"
#include "image_files/image_files.hpp"

#include <OpenImageIO/imageio.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>

namespace voxtier {
namespace {

namespace fs = std::filesystem;

fs::path scratch() {
    return test::scratchDir("voxtier_render_output", true);
}

std::string write(const std::string& name, const std::string& text) {
    return test::writeText(scratch(), name, text);
}

/// A box at the origin; a static camera close to it and a 1 s path at 10 fps from farther away.
std::string pathScene(bool positionedCamera, bool withPath = true) {
    std::string cam = R"("camera": {)" +
                      std::string(positionedCamera ? R"("position": [0, 1, 3], )" : "") +
                      R"("target": [0, 0.5, 0], "size": [64, 48]})";
    std::string path = R"(, "camera_path": {"fps": 10, "keys": [
        {"time": 0, "position": [0, 1, 8], "target": [0, 0.5, 0]},
        {"time": 1, "position": [2, 1, 3], "target": [0, 0.5, 0]}]})";
    return "{" + cam + (withPath ? path : "") +
           R"(, "models": [{"name": "b", "generator": "box"}], "entities": [{"model": "b"}]})";
}

Image render(const std::string& args, const std::string& out) {
    const test::CliRun r = test::runCli("render " + args + " --mode reference -o " + out);
    EXPECT_EQ(r.status, 0) << args << ": " << r.err;
    return readColorImage(out);
}

bool sameColor(const Image& a, const Image& b) {
    return a.width == b.width && a.height == b.height && a.color == b.color;
}

// A plain render shows the static camera when the file positions one, else the path's frame 0.
TEST(RenderOutput, PlainRenderFollowsTheCameraRule) {
    const fs::path d = scratch();
    const std::string withPath = write("with_path.json", pathScene(true));
    const std::string noPath = write("no_path.json", pathScene(true, false));
    const std::string unpositioned = write("unpositioned.json", pathScene(false));
    const Image plain = render(withPath, (d / "plain.png").string());
    EXPECT_TRUE(sameColor(plain, render(noPath, (d / "static.png").string())));
    const Image frame0 = render(withPath + " --frame 0", (d / "frame0.png").string());
    EXPECT_FALSE(sameColor(plain, frame0)) << "the static camera and the path start coincide";
    EXPECT_TRUE(sameColor(render(unpositioned, (d / "u.png").string()),
                          render(unpositioned + " --frame 0", (d / "u0.png").string())));
}

TEST(RenderOutput, FramesRendersTheRangeWithItsStep) {
    const fs::path d = scratch();
    const std::string scene = write("s.json", pathScene(true));
    const test::CliRun r = test::runCli("render " + scene + " --mode reference --frames 2:8:3 -o " +
                                        (d / "r.png").string());
    ASSERT_EQ(r.status, 0) << r.err;
    std::vector<std::string> files;
    for (const auto& f : fs::directory_iterator(d)) files.push_back(f.path().filename().string());
    std::sort(files.begin(), files.end());
    EXPECT_EQ(files,
              (std::vector<std::string>{"r_0002.png", "r_0005.png", "r_0008.png", "s.json"}));
    EXPECT_NE(r.out.find("[3/3, ~0 s left]"), std::string::npos) << r.out;
    EXPECT_NE(r.out.find("[1/3, ~"), std::string::npos) << r.out;
    // Frame 5 of the range is the path's frame 5.
    EXPECT_TRUE(sameColor(readColorImage(d / "r_0005.png"),
                          render(scene + " --frame 5", (d / "f5.png").string())));
    EXPECT_FALSE(sameColor(readColorImage(d / "r_0002.png"), readColorImage(d / "r_0005.png")));
}

TEST(RenderOutput, FrameOptionsThatCannotBeHonouredAreErrors) {
    const std::string scene = write("s.json", pathScene(true));
    const struct {
        std::string args, expect;
        int status;
    } cases[] = {
        {"--path --frame 3", "--path excludes --frame", 2},
        {"--path --time 0.5", "--path excludes --time", 2},
        {"--path --frames 1:2", "--path excludes --frames", 2},
        {"--frames 3:2", "FIRST:LAST[:STEP]", 2},
        {"--frames 1:2:0", "FIRST:LAST[:STEP]", 2},
        {"--frames 2:11", "frame 11 is past the camera path's last frame 10", 1},
        {"--frame 11", "--frame: frame 11 is past the camera path's last frame 10", 1},
    };
    for (const auto& c : cases) {
        const test::CliRun r = test::runCli("render " + scene + " --mode reference " + c.args +
                                            " -o " + (scratch() / "x.png").string());
        EXPECT_EQ(r.status, c.status) << c.args << ": " << r.err;
        EXPECT_NE(r.err.find(c.expect), std::string::npos) << c.args << ": " << r.err;
        EXPECT_EQ(test::lineCount(r.err), 1u) << r.err;
    }
}

// --path to .gif: one file, one subimage per frame, the path's frame rate, and every frame
// decodes to the frame's PNG pixel for pixel (a flat-shaded box and a background: GIF's 256
// colours hold them without loss).
TEST(RenderOutput, PathToGifIsOneAnimatedGif) {
    const fs::path d = scratch();
    const std::string scene = write("s.json", pathScene(true));
    const std::string gif = (d / "anim.gif").string();
    const test::CliRun r = test::runCli("render " + scene + " --mode reference --path -o " + gif);
    ASSERT_EQ(r.status, 0) << r.err;
    EXPECT_EQ(std::distance(fs::directory_iterator(d), fs::directory_iterator()), 2)
        << "only the scene and the GIF";
    auto in = OIIO::ImageInput::open(gif);
    ASSERT_TRUE(in) << OIIO::geterror();
    int subimages = 0;
    while (in->seek_subimage(subimages, 0)) ++subimages;
    EXPECT_EQ(subimages, 11); // 1 s at 10 fps, both ends
    ASSERT_TRUE(in->seek_subimage(0, 0));
    const OIIO::ImageSpec& spec = in->spec();
    EXPECT_EQ(spec.width, 64);
    int fps[2] = {0, 1}; // GIF stores a delay in 1/100 s: OIIO reads it back as 100/delay
    ASSERT_TRUE(spec.getattribute("FramesPerSecond", OIIO::TypeRational, fps));
    EXPECT_EQ(double(fps[0]) / fps[1], 10.0) << fps[0] << "/" << fps[1];
    EXPECT_EQ(r.err, "") << "every frame is exact: nothing to say";
    // Frame k of the GIF is the path's frame k, as the PNGs of the same frames have it.
    const test::CliRun pngs =
        test::runCli("render " + scene + " --mode reference --path -o " + (d / "f.png").string());
    ASSERT_EQ(pngs.status, 0) << pngs.err;
    for (int k = 0; k < subimages; ++k) {
        ASSERT_TRUE(in->seek_subimage(k, 0));
        const auto ch = std::size_t(in->spec().nchannels);
        std::vector<std::uint8_t> px(std::size_t(spec.width * spec.height) * ch);
        ASSERT_TRUE(in->read_image(k, 0, 0, int(ch), OIIO::TypeDesc::UINT8, px.data()));
        char name[32];
        std::snprintf(name, sizeof name, "f_%04d.png", k);
        const Image png = readColorImage(d / name);
        std::size_t differing = 0;
        for (std::size_t i = 0; i < png.pixelCount(); ++i)
            for (int c = 0; c < 3; ++c)
                differing += px[i * ch + std::size_t(c)] != channel(png.color[i], c);
        EXPECT_EQ(differing, 0u) << "frame " << k;
    }
}

// EXR colour is linear light: the sRGB palette colour decoded, tagged as linear.
TEST(RenderOutput, ExrHoldsLinearColourOfTheSrgbPalette) {
    const fs::path d = scratch();
    // ambient 1, diffuse 0: every face shows the palette colour exactly.
    const std::string scene = write("s.json", R"({"camera": {"position": [0, 0.4, 3],
        "target": [0, 0.4, 0], "size": [64, 48]}, "light": {"ambient": 1, "diffuse": 0},
        "models": [{"name": "b", "generator": "box", "color": [200, 100, 50]}],
        "entities": [{"model": "b"}]})");
    const Image png = render(scene, (d / "a.png").string());
    const std::string exr = (d / "a.exr").string();
    ASSERT_EQ(test::runCli("render " + scene + " --mode reference -o " + exr).status, 0);
    auto in = OIIO::ImageInput::open(exr);
    ASSERT_TRUE(in) << OIIO::geterror();
    const OIIO::ImageSpec spec = in->spec();
    ASSERT_EQ(spec.nchannels, 6);
    EXPECT_EQ(spec.get_string_attribute("oiio:ColorSpace"), "Linear");
    std::vector<float> px(std::size_t(spec.width * spec.height * 6));
    ASSERT_TRUE(in->read_image(0, 0, 0, 6, OIIO::TypeDesc::FLOAT, px.data()));
    const auto linear = [](double code) {
        const double c = code / 255.0;
        return c <= 0.04045 ? c / 12.92 : std::pow((c + 0.055) / 1.055, 2.4);
    };
    const std::size_t centre = png.index(32, 24), corner = png.index(0, 0);
    ASSERT_EQ(png.color[centre], packRgba(200, 100, 50)) << "the box is not at the centre";
    EXPECT_NEAR(px[centre * 6 + 0], linear(200), 1e-6); // 0.5776
    EXPECT_NEAR(px[centre * 6 + 1], linear(100), 1e-6); // 0.1274
    EXPECT_NEAR(px[centre * 6 + 2], linear(50), 1e-6);  // 0.0319
    EXPECT_EQ(px[centre * 6 + 3], 1.0f);
    EXPECT_GT(px[centre * 6 + 4], 2.0f); // Z: the box centre is ~3 m ahead
    EXPECT_LT(px[centre * 6 + 4], 3.5f);
    EXPECT_EQ(px[centre * 6 + 5], 0.0f); // id of the one entity
    EXPECT_TRUE(std::isinf(px[corner * 6 + 4]));
    EXPECT_EQ(px[corner * 6 + 5], -1.0f);
}

// Alpha 0 exactly where no sprite is drawn, 255 on every sprite pixel (outlines included), by
// --alpha or a scene background [r, g, b, 0], with the CPU reference and the Vulkan near tier.
TEST(RenderOutput, TransparentBackgroundOnlyWhereNoSpriteIsDrawn) {
    const fs::path d = scratch();
    const std::string opaque = write("opaque.json", pathScene(true, false));
    std::string clear = pathScene(true, false);
    clear.insert(1, R"("background": [40, 44, 52, 0], )");
    const std::string transparent = write("transparent.json", clear);
    const Image base = render(opaque, (d / "base.png").string());
    const std::size_t outline =
        std::size_t(std::count(base.color.begin(), base.color.end(), packRgba(0, 0, 0)));
    ASSERT_GT(outline, 0u);
    const std::string near = (d / "near.png").string();
    ASSERT_EQ(test::runCli("render " + opaque + " --alpha --mode near -o " + near).status, 0);
    for (const Image& im :
         {render(opaque + " --alpha", (d / "alpha.png").string()),
          render(transparent, (d / "scene.png").string()), readColorImage(near)}) {
        std::size_t transparentPixels = 0;
        for (std::size_t i = 0; i < im.pixelCount(); ++i) {
            const bool background = base.color[i] == packRgba(40, 44, 52);
            ASSERT_EQ(channel(im.color[i], 3), background ? 0u : 255u) << "pixel " << i;
            // Sprite colours unchanged (OIIO reads a transparent PNG pixel premultiplied: 0).
            if (!background) {
                ASSERT_EQ(im.color[i], base.color[i]) << "pixel " << i;
            }
            transparentPixels += background;
        }
        EXPECT_GT(transparentPixels, im.pixelCount() / 2);
    }
    // EXR alpha too.
    const std::string exr = (d / "a.exr").string();
    ASSERT_EQ(test::runCli("render " + transparent + " --mode reference -o " + exr).status, 0);
    auto in = OIIO::ImageInput::open(exr);
    ASSERT_TRUE(in);
    std::vector<float> px(base.pixelCount() * 6);
    ASSERT_TRUE(in->read_image(0, 0, 0, 6, OIIO::TypeDesc::FLOAT, px.data()));
    for (std::size_t i = 0; i < base.pixelCount(); ++i)
        if (base.color[i] == packRgba(40, 44, 52)) {
            ASSERT_EQ(px[i * 6 + 3], 0.0f) << i;
            ASSERT_EQ(px[i * 6 + 0], 0.0f) << "EXR colour is premultiplied by alpha: " << i;
        } else {
            ASSERT_EQ(px[i * 6 + 3], 1.0f) << i;
        }
}

// The small CLI messages (issue 14 item 8): one line each, with what the user needs to fix it.
TEST(RenderOutput, CliMessagesSayWhatWorks) {
    const std::string scene = write("s.json", pathScene(true));
    const std::string missingVox =
        write("missing.json", R"({"models": [{"name": "v", "vox": "nope/missing.vox"}]})");
    const struct {
        std::string args, expect;
        int status;
    } cases[] = {
        {"rendr " + scene, "unknown command 'rendr' (did you mean 'render'?)", 2},
        {"bak", "unknown command 'bak' (did you mean 'bake'?)", 2},
        {"render " + scene + " -o x",
         "--out: expected an image file name ending in one of .png, .exr, .gif, .tif, .jpg, .pam, "
         "got 'x'",
         2},
        {"render " + scene + " -o out/x.bogus", "ending in one of .png, .exr", 2},
        {"render " + missingVox,
         "('nope/missing.vox' is resolved against the scene file's folder, '" + scratch().string() +
             "')",
         1},
    };
    for (const auto& c : cases) {
        const test::CliRun r = test::runCli(c.args);
        EXPECT_EQ(r.status, c.status) << c.args << ": " << r.err;
        EXPECT_NE(r.err.find(c.expect), std::string::npos) << c.args << ": " << r.err;
        EXPECT_EQ(test::lineCount(r.err), 1u) << r.err;
    }
    const test::CliRun v = test::runCli("--version");
    EXPECT_EQ(v.status, 0);
    EXPECT_EQ(v.out, std::string("voxtier ") + VOXTIER_TEST_VERSION + "\n");
}

// `render FILE.vox` of a file with a scene graph draws what a scene's vox_scenes entry of that
// file draws, seen by the same camera (frameEntities); --model N draws one model.
TEST(RenderOutput, VoxSceneRenderEqualsVoxScenesInAScene) {
    const fs::path d = scratch();
    const std::string vox =
        std::string(VOXTIER_SOURCE_DIR) + "/scenes/vox/opengametools/test_multiple_model_scene.vox";
    const Image cli = render(vox + " --size 160x120 --view 40,25", (d / "cli.png").string());
    const Image one =
        render(vox + " --size 160x120 --view 40,25 --model 0", (d / "m0.png").string());

    // "models" needs an entry; an unused one does not change the image.
    Scene scene = loadSceneText(R"({"models": [{"name": "unused", "generator": "voxel"}],
        "vox_scenes": [{"vox": ")" + vox +
                                    R"("}]})",
                                "vox_scenes.json", d);
    ASSERT_GT(scene.entities.size(), 1u);
    ModelView view;
    view.azimuthDeg = 40;
    view.elevationDeg = 25;
    view.width = 160;
    view.height = 120;
    frameEntities(scene, view);
    FrameRenderer renderer(scene, FrameOptions{NearBackend::Reference});
    const Image expected = renderer.render(0.0, RenderMode::Reference).image;
    EXPECT_TRUE(sameColor(cli, expected)) << "the .vox render differs from vox_scenes";
    EXPECT_FALSE(sameColor(cli, one)) << "--model 0 drew the whole scene";
}

TEST(RenderOutput, VoxOptionsThatWouldBeIgnoredAreErrors) {
    const std::string vox = std::string(VOXTIER_SOURCE_DIR) + "/scenes/vox/mmmm/chr_cop1.vox";
    const std::string out = " -o " + (scratch() / "x.png").string();
    const struct {
        std::string args, expect;
        int status;
    } cases[] = {
        {"--frame 2", "--frame: applies to a scene input only", 2},
        {"--time 1", "--time: applies to a scene input only", 2},
        {"--path", "--path: applies to a scene input only", 2},
        {"--distance 0.3", "--distance: at 0.3 m the camera is inside the model's box", 1},
    };
    for (const auto& c : cases) {
        const test::CliRun r = test::runCli("render " + vox + " " + c.args + out);
        EXPECT_EQ(r.status, c.status) << c.args << ": " << r.err;
        EXPECT_NE(r.err.find(c.expect), std::string::npos) << c.args << ": " << r.err;
        EXPECT_EQ(test::lineCount(r.err), 1u) << r.err;
    }
    EXPECT_EQ(test::runCli("render " + vox + " --distance 8" + out).status, 0);
}

// The ground is drawn wherever no sprite is, in every mode; sprites are always over it and
// unchanged by it; above the horizon the background stays.
TEST(RenderOutput, GroundIsBehindEverySpriteInEveryMode) {
    const fs::path d = scratch();
    const std::string plain = pathScene(true, false);
    std::string grounded = plain;
    grounded.insert(1, R"("ground": {"spacing": 0.5, "fade_distance": 40}, )");
    const std::string a = write("plain.json", plain), b = write("ground.json", grounded);
    for (const char* mode : {"reference", "far", "hybrid"}) {
        const auto png = [&](const std::string& scene, const char* tag) {
            const std::string out = (d / (std::string(mode) + tag + ".png")).string();
            const test::CliRun r =
                test::runCli("render " + scene + " --mode " + mode + " -o " + out);
            EXPECT_EQ(r.status, 0) << r.err;
            return readColorImage(out);
        };
        const Image without = png(a, "_plain"), with = png(b, "_ground");
        const Rgba8 bg = packRgba(40, 44, 52);
        std::size_t sprite = 0, ground = 0;
        for (std::size_t i = 0; i < with.pixelCount(); ++i) {
            if (without.color[i] != bg) {
                ASSERT_EQ(with.color[i], without.color[i]) << mode << ": sprite pixel " << i;
                ++sprite;
            } else {
                ground += with.color[i] != bg;
            }
        }
        EXPECT_GT(sprite, 50u) << mode;
        EXPECT_GT(ground, with.pixelCount() / 4) << mode;
        // The camera looks down at the box from 1 m up: the top row is above the horizon.
        for (int x = 0; x < with.width; ++x) EXPECT_EQ(with.color[with.index(x, 0)], bg) << mode;
    }
}

// A cross-fading entity counts once in the status line (as fading), and the overlay shows it in
// a green no tinted near or far sprite can take, next to a legend.
TEST(RenderOutput, FadingEntityCountsOnceAndHasItsOwnOverlayColour) {
    const fs::path d = scratch();
    std::string text = pathScene(true);
    // The path closes from 8 m to 3.7 m: far at first, back to near below 4.5 m, fading 30 frames.
    text.insert(1, R"("selector": {"near_at": 4.5, "far_at": 5, "crossfade_frames": 30}, )");
    const std::string scene = write("s.json", text);
    const test::CliRun r = test::runCli(
        "render " + scene + " --mode hybrid --near-backend reference --size 160x120 --path -o " +
        (d / "f.png").string() + " --overlay " + (d / "o.png").string());
    ASSERT_EQ(r.status, 0) << r.err;
    int fadingFrames = 0, lines = 0;
    std::istringstream out(r.out);
    for (std::string line; std::getline(out, line);) {
        if (line.rfind("11 frames in ", 0) == 0) continue; // the run's total, after the frames
        if (line.rfind("far tier: ", 0) == 0) continue;    // --far-backend auto's choice, once
        int n = 0, f = 0, x = 0;
        const auto at = line.find("culled; ");
        ASSERT_NE(at, std::string::npos) << line;
        ASSERT_EQ(std::sscanf(line.c_str() + at, "culled; %d near, %d far, %d fading", &n, &f, &x),
                  3)
            << line;
        EXPECT_EQ(n + f + x, 1) << "one visible entity, counted once: " << line;
        fadingFrames += x;
        ++lines;
    }
    EXPECT_EQ(lines, 11);
    ASSERT_GT(fadingFrames, 0) << r.out;
    const auto green = [](const Image& im) {
        std::size_t n = 0;
        for (Rgba8 c : im.color)
            n += channel(c, 0) <= 63 && channel(c, 2) <= 63 && channel(c, 1) >= 191;
        return n;
    };
    const Image first = readColorImage(d / "o_0000.png"), last = readColorImage(d / "o_0010.png");
    EXPECT_GT(green(first), 0u) << "the legend's swatch";
    EXPECT_GT(green(last), green(first) + 50) << "the fading box is green";
    // The legend: the near and far swatches in their tints.
    EXPECT_EQ(first.color[first.index(8, 8)], packRgba(60, 140, 255));
    EXPECT_EQ(first.color[first.index(8, 24)], packRgba(255, 150, 40));
}

} // namespace
} // namespace voxtier
