// What a new user trips over on the command line (issues 27 and 38), end to end through the
// binary: a .vox preview is exact, an approximate far sprite is said once, --time is range-checked
// like --frame, --alpha is refused where the format cannot hold it, an unknown option gets a "did
// you mean", GIF delays keep the path's frame rate, and a path render ends with its wall time;
// the status line gives a frame's time and its writing apart and counts an edit's refreshes, an
// empty image says why, `info` on a scene says what it is, a missing model names the folder it
// was looked for in, the id image has a key, and the pops summary says what the --pops CSV holds.
#include "cli_support.hpp"
#include "image_files/image_files.hpp"

#include <OpenImageIO/imageio.h>
#include <gtest/gtest.h>
#include <sys/stat.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <map>
#include <regex>
#include <sstream>
#include <string>
#include <vector>

namespace voxtier {
namespace {

namespace fs = std::filesystem;

fs::path scratch() {
    return test::scratchDir("voxtier_cli_usability", true);
}

std::string vox(const std::string& rel) {
    return std::string(VOXTIER_SOURCE_DIR) + "/scenes/vox/" + rel;
}

/// A box and a 1 s camera path at `fps`.
std::string pathScene(double fps) {
    return test::writeText(scratch(), "s.json",
                           R"({"camera": {"target": [0, 0.5, 0], "size": [48, 32]},
            "camera_path": {"fps": )" +
                               std::to_string(fps) + R"(, "keys": [
              {"time": 0, "position": [0, 1, 8], "target": [0, 0.5, 0]},
              {"time": 1, "position": [2, 1, 3], "target": [0, 0.5, 0]}]},
            "models": [{"name": "b", "generator": "box"}], "entities": [{"model": "b"}]})");
}

/// One error line: exit `status`, stderr is one line holding `expect`.
void expectOneLine(const std::string& args, int status, const std::string& expect) {
    const test::CliRun r = test::runCli(args);
    EXPECT_EQ(r.status, status) << args << ": " << r.err;
    EXPECT_NE(r.err.find(expect), std::string::npos) << args << ": " << r.err;
    EXPECT_EQ(test::lineCount(r.err), 1u) << args << ": " << r.err;
}

// The two cases issue 27 found approximate: the bundled tree (a scene graph of three shapes,
// drawn far in hybrid) and the fire truck at 45 m. Without --mode, each equals the reference.
TEST(CliUsability, VoxPreviewEqualsTheReference) {
    const struct {
        std::string input, args;
    } cases[] = {{vox("vox-reader.js/tree.vox"), ""}, {vox("mmmm/veh_fire.vox"), " --distance 45"}};
    for (const auto& c : cases) {
        const std::string preview = (scratch() / "preview.png").string();
        const std::string reference = (scratch() / "reference.png").string();
        const test::CliRun p = test::runCli("render " + c.input + c.args + " -o " + preview);
        ASSERT_EQ(p.status, 0) << p.err;
        // Exact: the near tier drew everything, and no far sprite needed a warning.
        EXPECT_TRUE(p.out.find(": near, frame 0") != std::string::npos ||
                    p.out.find(": reference, frame 0") != std::string::npos)
            << p.out;
        EXPECT_NE(p.out.find("0 far, 0 fading"), std::string::npos) << p.out;
        EXPECT_EQ(p.err, "");
        const test::CliRun r =
            test::runCli("render " + c.input + c.args + " --mode reference -o " + reference);
        ASSERT_EQ(r.status, 0) << r.err;
        const Image a = readColorImage(preview), b = readColorImage(reference);
        ASSERT_EQ(a.width, b.width);
        ASSERT_EQ(a.height, b.height);
        std::size_t differing = 0;
        for (std::size_t i = 0; i < a.pixelCount(); ++i) differing += a.color[i] != b.color[i];
        EXPECT_EQ(differing, 0u) << c.input << c.args;
    }
}

// Asked for hybrid, the tree draws far sprites predicted several vpx off: one warning line with
// the count, the worst figure and the way out; stdout still has the status line.
TEST(CliUsability, ApproximateFarSpritesGetOneWarningLine) {
    const test::CliRun r = test::runCli("render " + vox("vox-reader.js/tree.vox") +
                                        " --mode hybrid -o " + (scratch() / "t.png").string());
    ASSERT_EQ(r.status, 0) << r.err;
    EXPECT_EQ(test::lineCount(r.err), 1u) << r.err;
    EXPECT_EQ(r.err.rfind("voxtier: warning: ", 0), 0u) << r.err;
    EXPECT_NE(r.err.find(" far sprites drawn from snapshots predicted to be off by over 1 virtual "
                         "pixel (worst "),
              std::string::npos)
        << r.err;
    EXPECT_NE(r.err.find("--mode near or --mode reference draws every entity exactly"),
              std::string::npos)
        << r.err;
    EXPECT_NE(r.out.find(": hybrid, frame 0"), std::string::npos) << r.out;
}

TEST(CliUsability, TimeIsRangeCheckedLikeFrame) {
    const std::string scene = pathScene(10);
    const std::string out = " --mode reference -o " + (scratch() / "x.png").string();
    expectOneLine("render " + scene + " --time 10" + out, 1,
                  "--time: t=10 s is past the camera path's last key at 1 s");
    expectOneLine("render " + scene + " --time -1" + out, 1,
                  "--time: t=-1 s is before the camera path's first key at 0 s");
    expectOneLine("render " + scene + " --time 1e308" + out, 1,
                  "--time: t=1e+308 s is past the camera path's last key at 1 s");
    EXPECT_EQ(test::runCli("render " + scene + " --time 1" + out).status, 0);
    // Without a path, --time is the animation time: at least 0, at most 1e6 s.
    const std::string noPath =
        test::writeText(scratch(), "n.json",
                        R"({"camera": {"position": [0, 1, 3], "target": [0, 0.5, 0],
                            "size": [48, 32]}, "models": [{"name": "b", "generator": "box"}],
                            "entities": [{"model": "b"}]})");
    expectOneLine("render " + noPath + " --time 1e308" + out, 1,
                  "--time: t=1e+308 s is outside [0, 1e+06] s (the scene has no camera path)");
    expectOneLine("render " + noPath + " --time -1" + out, 1, "--time: t=-1 s is outside");
    EXPECT_EQ(test::runCli("render " + noPath + " --time 2" + out).status, 0);
}

// GIF and JPEG cannot hold the transparent background: refused in one line. TIFF holds it.
TEST(CliUsability, AlphaNeedsAFormatThatHoldsIt) {
    const std::string scene = pathScene(10);
    for (const char* ext : {".gif", ".jpg"})
        expectOneLine("render " + scene + " --alpha --mode reference -o " +
                          (scratch() / (std::string("a") + ext)).string(),
                      2, std::string("--alpha: a ") + ext + " file cannot hold the transparency");
    expectOneLine("render " + scene + " --alpha --path --mode reference -o " +
                      (scratch() / "anim.gif").string(),
                  2, "--alpha: a .gif file cannot hold the transparency");
    const std::string tif = (scratch() / "a.tif").string();
    const test::CliRun r = test::runCli("render " + scene + " --alpha --mode reference -o " + tif);
    ASSERT_EQ(r.status, 0) << r.err;
    EXPECT_EQ(channel(readColorImage(tif).color[0], 3), 0u) << "the corner is background";
}

TEST(CliUsability, UnknownOptionsGetADidYouMean) {
    const std::string scene = pathScene(10);
    expectOneLine("render " + scene + " --sizes 10x10", 2,
                  "voxtier: error: unknown option '--sizes' for render (did you mean '--size'?)");
    expectOneLine("render " + scene + " --frobnicate", 2,
                  "voxtier: error: unknown option '--frobnicate' for render (see --help)");
    // A negative value is a value, not an unknown option.
    const test::CliRun r = test::runCli("render " + vox("mmmm/chr_cop1.vox") +
                                        " --view -30,20 -o " + (scratch() / "v.png").string());
    EXPECT_EQ(r.status, 0) << r.err;
}

// A .vox has no camera path: --path's message says so, and does not send the user to --model.
TEST(CliUsability, PathOnAVoxSaysWhy) {
    const test::CliRun r = test::runCli("render " + vox("mmmm/chr_cop1.vox") + " --path");
    EXPECT_EQ(r.status, 2) << r.err;
    EXPECT_EQ(test::lineCount(r.err), 1u) << r.err;
    EXPECT_NE(r.err.find("--path: applies to a scene input only (a .vox has no camera path"),
              std::string::npos)
        << r.err;
    EXPECT_EQ(r.err.find("--model"), std::string::npos) << r.err;
}

TEST(CliUsability, HelpListsEveryOutputFormat) {
    const test::CliRun r = test::runCli("render --help");
    ASSERT_EQ(r.status, 0) << r.err;
    for (const char* ext : {".png", ".exr", ".tif", ".jpg", ".gif", ".pam"})
        EXPECT_NE(r.out.find(ext), std::string::npos) << ext << " missing from:\n" << r.out;
}

// 30 fps cannot be one GIF delay (1/100 s): the delays alternate 3, 3, 4 so that 30 frames
// last exactly 1 s. The path render ends with its wall time; not on a terminal, no progress.
TEST(CliUsability, GifDelaysKeepThePathFrameRate) {
    const std::string scene = pathScene(30);
    const std::string gif = (scratch() / "anim.gif").string();
    const test::CliRun r = test::runCli("render " + scene + " --mode reference --path -o " + gif);
    ASSERT_EQ(r.status, 0) << r.err;
    EXPECT_EQ(r.err, "") << "no progress line when stderr is not a terminal";
    EXPECT_NE(r.out.find("31 frames in "), std::string::npos) << r.out;
    EXPECT_NE(r.out.find(" s (wall time: loading, rendering and writing) -> " + gif),
              std::string::npos)
        << r.out;
    auto in = OIIO::ImageInput::open(gif);
    ASSERT_TRUE(in) << OIIO::geterror();
    std::vector<int> delays;
    for (int k = 0; in->seek_subimage(k, 0); ++k) {
        int fps[2] = {0, 1}; // OIIO reads a GIF delay d back as 100/d
        ASSERT_TRUE(in->spec().getattribute("FramesPerSecond", OIIO::TypeRational, fps));
        ASSERT_EQ(fps[0], 100);
        delays.push_back(fps[1]);
    }
    ASSERT_EQ(delays.size(), 31u);
    int first30 = 0;
    for (std::size_t k = 0; k < 30; ++k) {
        EXPECT_TRUE(delays[k] == 3 || delays[k] == 4) << k << ": " << delays[k];
        first30 += delays[k];
    }
    EXPECT_EQ(first30, 100);
    EXPECT_EQ(delays[0], 3);
    EXPECT_EQ(delays[1], 4);
    EXPECT_EQ(delays[2], 3);
}

// bake says what it will write before writing it, and the figures hold: the files and their bytes
// exactly (the snapshot lattice fixes each file's size), the disk they take within 5 %.
TEST(CliUsability, BakeEstimatesWhatItWrites) {
    const fs::path dir = scratch() / "estimate";
    fs::remove_all(dir);
    const test::CliRun r =
        test::runCli("bake " + vox("mmmm/chr_cop1.vox") + " --level 2 --cache-dir " + dir.string());
    ASSERT_EQ(r.status, 0) << r.err;
    unsigned long long snapshots = 0, files = 0, block = 0;
    double mb = 0, diskMb = 0;
    const auto at = r.out.find("estimate: ");
    ASSERT_NE(at, std::string::npos) << r.out;
    ASSERT_EQ(std::sscanf(r.out.c_str() + at,
                          "estimate: %llu snapshots in %llu pack file, %lf MiB, %lf MiB on disk "
                          "(%llu-byte",
                          &snapshots, &files, &mb, &diskMb, &block),
              5)
        << r.out;
    std::uint64_t count = 0, bytes = 0, disk = 0;
    for (const auto& e : fs::recursive_directory_iterator(dir)) {
        struct stat st {};
        ASSERT_EQ(::stat(e.path().c_str(), &st), 0);
        disk += std::uint64_t(st.st_blocks) * 512;
        if (!e.is_regular_file() || e.path().filename() == ".lock") continue; // (empty)
        ++count;
        bytes += e.file_size();
    }
    EXPECT_EQ(snapshots, 98u);
    EXPECT_EQ(files, 1u); // one model frame, one pack
    EXPECT_EQ(count, files);
    const double mib = double(1 << 20);
    EXPECT_NEAR(mb * mib, double(bytes), 0.005 * mib + 0.001 * double(bytes));
    // Within 5 %, past the printed figure's rounding to 0.01 MiB.
    EXPECT_NEAR(diskMb * mib, double(disk), 0.005 * mib + 0.05 * double(disk)) << "block " << block;
}

// A bake estimated over 256 MiB on disk is refused before it writes anything, with one line
// saying how to go ahead (the 267-voxel character at --level 64 and sigma 4: 98,306 snapshots,
// 487 MB).
TEST(CliUsability, AHugeBakeIsRefusedWithoutYes) {
    const fs::path dir = scratch() / "huge";
    fs::remove_all(dir);
    expectOneLine("bake " + vox("mmmm/chr_cop1.vox") + " --level 64 --sigma 4 --cache-dir " +
                      dir.string(),
                  1, "add --yes to go ahead");
    EXPECT_FALSE(fs::exists(dir) && !fs::is_empty(dir)) << "nothing written";
}

/// The rows of a CSV file (no quoted fields), the header first.
std::vector<std::vector<std::string>> readCsv(const fs::path& file) {
    std::ifstream in(file);
    std::vector<std::vector<std::string>> rows;
    std::string line;
    while (std::getline(in, line)) {
        std::vector<std::string> cells;
        std::stringstream ss(line);
        std::string cell;
        while (std::getline(ss, cell, ',')) cells.push_back(cell);
        rows.push_back(cells);
    }
    return rows;
}

/// The index of column `name` in a CSV's header.
std::size_t column(const std::vector<std::vector<std::string>>& csv, const std::string& name) {
    const auto& h = csv.at(0);
    const auto it = std::find(h.begin(), h.end(), name);
    EXPECT_NE(it, h.end()) << name;
    return std::size_t(it - h.begin());
}

/// The lines of `text` that contain `part`.
std::vector<std::string> linesWith(const std::string& text, const std::string& part) {
    std::vector<std::string> out;
    std::stringstream ss(text);
    std::string line;
    while (std::getline(ss, line))
        if (line.find(part) != std::string::npos) out.push_back(line);
    return out;
}

// The status line gives the frame's own time (the --csv frame_ms) and the time its files took,
// apart: writing a PNG took several times the frame before issue 38, inside one figure.
TEST(CliUsability, StatusLineGivesFrameAndWritingTimesApart) {
    const std::string scene = pathScene(10);
    const fs::path d = scratch();
    const test::CliRun r =
        test::runCli("render " + scene + " --mode reference --frames 0:2 -o " +
                     (d / "f.png").string() + " --csv " + (d / "c.csv").string());
    ASSERT_EQ(r.status, 0) << r.err;
    const auto csv = readCsv(d / "c.csv");
    ASSERT_EQ(csv.size(), 4u);
    const std::vector<std::string> lines = linesWith(r.out, ": reference, frame ");
    ASSERT_EQ(lines.size(), 3u) << r.out;
    const std::regex times(R"(, frame ([0-9.]+) ms, writing ([0-9.]+) ms -> )");
    for (std::size_t k = 0; k < lines.size(); ++k) {
        std::smatch m;
        ASSERT_TRUE(std::regex_search(lines[k], m, times)) << lines[k];
        const double frameMs = std::stod(m[1]),
                     csvMs = std::stod(csv[k + 1][column(csv, "frame_ms")]);
        EXPECT_NEAR(frameMs, csvMs, 0.05 + 1e-9) << lines[k];
        EXPECT_NE(lines[k].find("-> " + (d / ("f_000" + std::to_string(k) + ".png")).string()),
                  std::string::npos)
            << lines[k];
    }
}

// A scripted edit makes the far snapshot of the model it changes stale: the frame that refreshes
// it says so on its status line, and only that frame.
TEST(CliUsability, StatusLineSaysWhenAnEditRefreshedSnapshots) {
    const std::string scene = test::writeText(scratch(), "edit.json", R"({
        "camera": {"position": [0, 1, 4], "target": [0, 0.5, 0], "size": [48, 32]},
        "models": [{"name": "b", "generator": "box"}], "entities": [{"model": "b"}],
        "edits": [{"frame": 2, "model": "b", "op": "clear", "min": [0, 0, 6], "max": [8, 8, 8]}]})");
    const test::CliRun r = test::runCli("render " + scene + " --mode far --frames 0:3 -o " +
                                        (scratch() / "e.png").string());
    ASSERT_EQ(r.status, 0) << r.err;
    const std::vector<std::string> lines = linesWith(r.out, ": far, frame ");
    ASSERT_EQ(lines.size(), 4u) << r.out;
    for (std::size_t k = 0; k < lines.size(); ++k) {
        // One entity seen from a still camera: one snapshot, baked at frame 0, refreshed at 2.
        const char* bakes = k == 0   ? ", 1 bake, "
                            : k == 2 ? ", 1 bake (1 after an edit made a snapshot stale), "
                                     : ", 0 bakes, ";
        EXPECT_NE(lines[k].find(bakes), std::string::npos) << lines[k];
    }
}

// An image with no entity in it says why in one line: each entity behind the camera, off screen
// or under half a pixel.
TEST(CliUsability, AnEmptyImageSaysWhyNothingDrew) {
    const std::string scene = test::writeText(scratch(), "empty.json", R"({
        "camera": {"position": [0, 1, 0], "target": [0, 1, -10], "size": [48, 32]},
        "models": [{"name": "b", "generator": "box"}],
        "entities": [{"model": "b", "position": [0, 0, 5]}, {"model": "b", "position": [40, 0, -5]},
                     {"model": "b", "position": [0, 0, -900]}]})");
    const test::CliRun r =
        test::runCli("render " + scene + " --mode reference -o " + (scratch() / "e.png").string());
    ASSERT_EQ(r.status, 0) << r.err;
    EXPECT_EQ(test::lineCount(r.err), 1u) << r.err;
    EXPECT_NE(
        r.err.find("voxtier: warning: the image shows no entity (of 3 entities: 1 behind the "
                   "camera, 1 off screen, 1 sub-pixel (under half a pixel across)); check the "
                   "camera's position and target"),
        std::string::npos)
        << r.err;
    // A path: how many frames, and the first one's reasons.
    const std::string path = test::writeText(scratch(), "path.json", R"({
        "camera": {"size": [48, 32]},
        "camera_path": {"fps": 10, "keys": [
            {"time": 0, "position": [0, 1, 4], "target": [0, 0.5, -10]},
            {"time": 0.5, "position": [0, 1, -4], "target": [0, 0.5, -10]}]},
        "models": [{"name": "b", "generator": "box"}], "entities": [{"model": "b"}]})");
    const test::CliRun p = test::runCli("render " + path + " --mode reference --path -o " +
                                        (scratch() / "p.png").string());
    ASSERT_EQ(p.status, 0) << p.err;
    EXPECT_EQ(test::lineCount(p.err), 1u) << p.err;
    // The camera passes the box at frame 3 (z = -0.8 m) and looks away from it from then on.
    EXPECT_NE(p.err.find("voxtier: warning: 3 of 6 frames show no entity (the first, frame 3, of "
                         "1 entity: 1 behind the camera); check"),
              std::string::npos)
        << p.err;
    // Where every frame shows an entity, nothing is said.
    const test::CliRun ok = test::runCli("render " + pathScene(10) + " --mode reference -o " +
                                         (scratch() / "ok.png").string());
    EXPECT_EQ(ok.err, "");
}

// `info` describes .vox files; given a scene, it says what the file is and what reads it, not
// what its first bytes are not.
TEST(CliUsability, InfoOnASceneSaysItIsAScene) {
    const std::string scene = std::string(VOXTIER_SOURCE_DIR) + "/scenes/default.json";
    expectOneLine("info " + scene, 1,
                  scene +
                      ": is a scene file (JSON), not a MagicaVoxel .vox file: `voxtier "
                      "render " +
                      scene + "` draws it");
    const test::CliRun r = test::runCli("info " + scene);
    EXPECT_EQ(r.err.find("magic"), std::string::npos) << r.err;
}

// A scene named without a folder resolves its models against the current folder, and the message
// says which folder that is (it named '' before).
TEST(CliUsability, AMissingModelNamesTheFolderItWasLookedFor) {
    const fs::path d = fs::canonical(scratch());
    test::writeText(d, "m.json", R"({"models": [{"name": "v", "vox": "nope/missing.vox"}]})");
    const test::CliRun r = test::runCli("render m.json", "cd '" + d.string() + "' &&");
    EXPECT_EQ(r.status, 1) << r.err;
    EXPECT_EQ(test::lineCount(r.err), 1u) << r.err;
    EXPECT_NE(r.err.find("file not found: 'nope/missing.vox' ('nope/missing.vox' is resolved "
                         "against the scene file's folder, the current folder '" +
                         d.string() + "')"),
              std::string::npos)
        << r.err;
    EXPECT_EQ(r.err.find("''"), std::string::npos) << r.err;
}

// The id image's key names the entity of every colour in it: checked against the EXR's id
// channel of the same frame, pixel by pixel.
TEST(CliUsability, IdImageHasAKeyFromColourToEntity) {
    const fs::path d = scratch();
    const std::string scene = test::writeText(d, "ids.json", R"({
        "camera": {"position": [0, 2, 6], "target": [0, 0.5, 0], "size": [96, 64]},
        "models": [{"name": "b", "generator": "box"}, {"name": "s", "generator": "sphere"}],
        "entities": [{"model": "b", "position": [-1.5, 0, 0], "name": "left, crate"},
                     {"model": "s", "position": [0, 0, 0]},
                     {"model": "b", "position": [1.5, 0, 0], "name": "right"},
                     {"model": "b", "position": [0, 0, 50]}]})");
    const test::CliRun r =
        test::runCli("render " + scene + " --mode reference -o " + (d / "f.exr").string() +
                     " --ids " + (d / "ids.png").string());
    ASSERT_EQ(r.status, 0) << r.err;
    // The key: entity, name, model, r, g, b (a name with a comma is quoted).
    std::ifstream in(d / "ids_key.csv");
    std::string line;
    std::getline(in, line);
    EXPECT_EQ(line, "entity,name,model,r,g,b");
    std::map<Rgba8, int> entityOf;
    std::vector<std::string> rows;
    while (std::getline(in, line)) {
        rows.push_back(line);
        const auto tail = line.rfind(',', line.rfind(',', line.rfind(',') - 1) - 1);
        unsigned rgb[3];
        ASSERT_EQ(std::sscanf(line.c_str() + tail, ",%u,%u,%u", &rgb[0], &rgb[1], &rgb[2]), 3);
        ASSERT_TRUE(entityOf.emplace(packRgba(rgb[0], rgb[1], rgb[2]), std::stoi(line)).second)
            << "two entities share a colour: " << line;
    }
    ASSERT_EQ(rows.size(), 3u) << "entities 0-2, not the one behind the camera";
    EXPECT_EQ(rows[0].rfind("0,\"left, crate\",b,", 0), 0u) << rows[0];
    EXPECT_EQ(rows[1].rfind("1,,s,", 0), 0u) << rows[1];
    EXPECT_EQ(rows[2].rfind("2,right,b,", 0), 0u) << rows[2];
    const Image ids = readColorImage(d / "ids.png");
    auto exr = OIIO::ImageInput::open((d / "f.exr").string());
    ASSERT_TRUE(exr) << OIIO::geterror();
    const OIIO::ImageSpec& spec = exr->spec();
    const int idChannel = spec.channelindex("id");
    ASSERT_GE(idChannel, 0);
    std::vector<float> id(std::size_t(spec.width * spec.height));
    ASSERT_TRUE(exr->read_image(0, 0, idChannel, idChannel + 1, OIIO::TypeDesc::FLOAT, id.data()));
    ASSERT_EQ(ids.pixelCount(), id.size());
    std::size_t drawn = 0;
    for (std::size_t p = 0; p < id.size(); ++p) {
        const Rgba8 c = ids.color[p] | 0xFF000000u;
        if (id[p] < 0) {
            ASSERT_EQ(c, packRgba(0, 0, 0)) << p;
            continue;
        }
        ++drawn;
        const auto it = entityOf.find(c);
        ASSERT_NE(it, entityOf.end()) << "pixel " << p << " has a colour the key lacks";
        ASSERT_EQ(it->second, int(id[p])) << p;
    }
    EXPECT_GT(drawn, 100u);
    // A format that does not keep the colours exactly would break the key: refused.
    for (const char* ext : {".gif", ".jpg"})
        expectOneLine("render " + scene + " --ids " + (d / "ids").string() + ext, 2,
                      std::string("--ids: a ") + ext +
                          " file does not keep every entity's colour (GIF holds 256, JPEG is "
                          "lossy)");
}

// The pops summary line says what the --pops CSV holds: the switches by kind, how many changed
// what is seen, the worst seen change, and how many exceed --pop-threshold.
TEST(CliUsability, PopsSummaryAgreesWithThePopsCsv) {
    const fs::path d = scratch();
    const std::string scene = test::writeText(d, "pops.json", R"({
        "camera": {"size": [96, 64], "fov_y": 50},
        "camera_path": {"fps": 10, "keys": [
            {"time": 0, "position": [0, 1, 2], "target": [0, 0.5, -20]},
            {"time": 3, "position": [0, 1, 30], "target": [0, 0.5, -20]}]},
        "selector": {"near_at": 14, "far_at": 16},
        "models": [{"name": "w", "generator": "box", "size": [40, 4, 30]},
                   {"name": "a", "generator": "arrow"}],
        "entities": [{"model": "w", "position": [0, 0, -6], "rotation_deg": [0, 17, 0]},
                     {"model": "a", "position": [0, 0, -9], "rotation_deg": [0, 40, 0]},
                     {"model": "a", "position": [5, 0, -9], "rotation_deg": [0, 20, 0]}]})");
    const test::CliRun r =
        test::runCli("render " + scene + " --path -o " + (d / "f.pam").string() + " --pops " +
                     (d / "pops.csv").string() + " --pop-threshold 20");
    ASSERT_EQ(r.status, 0) << r.err;
    const auto csv = readCsv(d / "pops.csv");
    ASSERT_GT(csv.size(), 2u);
    std::size_t tier = 0, view = 0, fade = 0, seen = 0, over = 0, worst = 0;
    for (std::size_t k = 1; k < csv.size(); ++k) {
        const std::string kind = csv[k][column(csv, "kind")];
        tier += kind == "tier", view += kind == "view", fade += kind == "fade";
        const std::size_t px = std::stoul(csv[k][column(csv, "seen_changed_pixels")]);
        seen += px > 0;
        over += px > 20;
        worst = std::max(worst, px);
    }
    const std::vector<std::string> summary = linesWith(r.out, "pops: ");
    ASSERT_EQ(summary.size(), 1u) << r.out;
    char expect[256];
    std::snprintf(expect, sizeof expect,
                  "pops: %zu switches in 31 frames (%zu tier, %zu view, %zu cross-fade steps), "
                  "%zu changed what is seen; worst seen: %zu px changed (entity ",
                  csv.size() - 1, tier, view, fade, seen, worst);
    EXPECT_EQ(summary[0].rfind(expect, 0), 0u) << summary[0] << "\nexpected: " << expect;
    EXPECT_NE(summary[0].find("; " + std::to_string(over) + " over 20 px seen (--pop-threshold)"),
              std::string::npos)
        << summary[0];
    // The threshold alone measures pops and prints the summary, without a CSV.
    const test::CliRun alone = test::runCli("render " + scene + " --path -o " +
                                            (d / "g.pam").string() + " --pop-threshold 20");
    ASSERT_EQ(alone.status, 0) << alone.err;
    EXPECT_EQ(linesWith(alone.out, "pops: "), summary);
}

// A GIF whose frames have more colours than 256 says so in one line and names a lossless format;
// one within 256 says nothing (CliUsability.GifDelaysKeepThePathFrameRate).
TEST(CliUsability, AGifThatCannotBeExactSaysSo) {
    std::string entities;
    for (int i = 0; i < 120; ++i) // 120 colours, each box showing two or three lit faces
        entities += std::string(i ? "," : "") + R"({"model": "m)" + std::to_string(i) +
                    R"(", "position": [)" + std::to_string((i % 12) - 6) + ", " +
                    std::to_string(i / 12) + ", 0]}";
    std::string models;
    for (int i = 0; i < 120; ++i)
        models += std::string(i ? "," : "") + R"({"name": "m)" + std::to_string(i) +
                  R"(", "generator": "box", "color": [)" + std::to_string(2 * i) + ", " +
                  std::to_string(255 - 2 * i) + ", " + std::to_string((37 * i) % 256) + "]}";
    const std::string scene = test::writeText(
        scratch(), "colours.json",
        R"({"camera": {"position": [4, 8, 14], "target": [0, 4, 0], "size": [160, 120]},
            "models": [)" +
            models + R"(], "entities": [)" + entities + "]}");
    const std::string gif = (scratch() / "c.gif").string();
    const test::CliRun r = test::runCli("render " + scene + " --mode reference -o " + gif);
    ASSERT_EQ(r.status, 0) << r.err;
    EXPECT_EQ(test::lineCount(r.err), 1u) << r.err;
    EXPECT_EQ(r.err.rfind("voxtier: warning: " + gif +
                              ": the image has more colours than GIF's 256 a frame (up to ",
                          0),
              0u)
        << r.err;
    EXPECT_NE(r.err.find("write .png (a sequence: numbered PNGs) or .pam"), std::string::npos)
        << r.err;
}

// The tests' scratch folders are named by the process id, which a later process can get again:
// the first time a process asks for its folder, what an earlier process of that pid left there
// is gone; later in the same process the folder keeps what the test wrote.
TEST(ScratchDir, AFolderLeftByAnEarlierProcessOfTheSamePidIsEmptiedOnce) {
    const fs::path stale = fs::path(::testing::TempDir()) /
                           ("voxtier_scratch_probe_" + std::to_string(::getpid())) /
                           ::testing::UnitTest::GetInstance()->current_test_info()->name();
    fs::create_directories(stale);
    std::ofstream(stale / "left_by_an_earlier_run.png") << "x";
    const fs::path d = test::scratchDir("voxtier_scratch_probe", true);
    ASSERT_EQ(d, stale);
    EXPECT_FALSE(fs::exists(d / "left_by_an_earlier_run.png"));
    std::ofstream(d / "mine.txt") << "y";
    EXPECT_EQ(test::scratchDir("voxtier_scratch_probe", true), d);
    EXPECT_TRUE(fs::exists(d / "mine.txt")) << "emptied once a process, not at every call";
    fs::remove_all(d.parent_path());
}

} // namespace
} // namespace voxtier
