// The .vox reader and `voxtier info`. Expected values come from outside the reader: the
// facts in scenes/vox/expected.json (parsed independently and cross-checked with ogt_vox),
// bytes decoded by hand in this file, and malformed files built here from the format
// description, byte by byte.
#include "cli_support.hpp"
#include "core/error.hpp"
#include "core/vox_reader.hpp"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>
#include <sys/wait.h>

#include <algorithm>
#include <array>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <iterator>
#include <map>
#include <random>
#include <set>
#include <span>
#include <string>
#include <string_view>
#include <unistd.h>
#include <vector>

namespace voxtier {
namespace {

using Bytes = std::vector<std::uint8_t>;
using Pairs = std::vector<std::pair<std::string, std::string>>;
using Mat3i = glm::mat<3, 3, int>;

std::string voxPath(const std::string& relative) {
    return std::string(VOXTIER_SOURCE_DIR) + "/scenes/vox/" + relative;
}

Bytes readBytes(const std::string& path) {
    std::ifstream in(path, std::ios::binary);
    EXPECT_TRUE(in) << path;
    return Bytes(std::istreambuf_iterator<char>(in), {});
}

std::int32_t getI32(const Bytes& b, std::size_t at) {
    return std::int32_t(std::uint32_t(b[at]) | std::uint32_t(b[at + 1]) << 8 |
                        std::uint32_t(b[at + 2]) << 16 | std::uint32_t(b[at + 3]) << 24);
}

// --- A tiny .vox writer, straight from the format description -------------------------------

void putI32(Bytes& b, std::int32_t v) {
    for (int i = 0; i < 4; ++i) b.push_back(std::uint8_t(std::uint32_t(v) >> (8 * i)));
}
void putStr(Bytes& b, std::string_view s) {
    putI32(b, std::int32_t(s.size()));
    b.insert(b.end(), s.begin(), s.end());
}
void putDict(Bytes& b, const Pairs& d) {
    putI32(b, std::int32_t(d.size()));
    for (const auto& [k, v] : d) {
        putStr(b, k);
        putStr(b, v);
    }
}
Bytes chunk(std::string_view id, const Bytes& content, const Bytes& children = {}) {
    Bytes b(id.begin(), id.end());
    putI32(b, std::int32_t(content.size()));
    putI32(b, std::int32_t(children.size()));
    b.insert(b.end(), content.begin(), content.end());
    b.insert(b.end(), children.begin(), children.end());
    return b;
}
Bytes concat(const std::vector<Bytes>& parts) {
    Bytes b;
    for (const auto& p : parts) b.insert(b.end(), p.begin(), p.end());
    return b;
}
Bytes voxFile(const std::vector<Bytes>& mainChildren, std::int32_t version = 150) {
    Bytes b{'V', 'O', 'X', ' '};
    putI32(b, version);
    const Bytes main = chunk("MAIN", {}, concat(mainChildren));
    b.insert(b.end(), main.begin(), main.end());
    return b;
}
Bytes sizeChunk(std::int32_t x, std::int32_t y, std::int32_t z) {
    Bytes c;
    putI32(c, x);
    putI32(c, y);
    putI32(c, z);
    return chunk("SIZE", c);
}
Bytes xyziChunk(const std::vector<std::array<std::uint8_t, 4>>& voxels) {
    Bytes c;
    putI32(c, std::int32_t(voxels.size()));
    for (const auto& v : voxels) c.insert(c.end(), v.begin(), v.end());
    return chunk("XYZI", c);
}
Bytes transformChunk(std::int32_t id, std::int32_t child, const Pairs& frame = {},
                     const Pairs& attributes = {}, std::int32_t layer = 0) {
    Bytes c;
    putI32(c, id);
    putDict(c, attributes);
    putI32(c, child);
    putI32(c, -1);
    putI32(c, layer);
    putI32(c, 1);
    putDict(c, frame);
    return chunk("nTRN", c);
}
Bytes groupChunk(std::int32_t id, const std::vector<std::int32_t>& children) {
    Bytes c;
    putI32(c, id);
    putDict(c, {});
    putI32(c, std::int32_t(children.size()));
    for (auto ch : children) putI32(c, ch);
    return chunk("nGRP", c);
}
Bytes shapeChunk(std::int32_t id, std::int32_t model) {
    Bytes c;
    putI32(c, id);
    putDict(c, {});
    putI32(c, 1);
    putI32(c, model);
    putDict(c, {});
    return chunk("nSHP", c);
}
Bytes layerChunk(std::int32_t id, const Pairs& attributes) {
    Bytes c;
    putI32(c, id);
    putDict(c, attributes);
    putI32(c, -1);
    return chunk("LAYR", c);
}
/// One 2x2x2 model with a single voxel of colour 1.
std::vector<Bytes> oneModel() {
    return {sizeChunk(2, 2, 2), xyziChunk({{0, 0, 0, 1}})};
}
/// oneModel plus root transform 0 -> group 1 -> transform 2 (frame attributes given) ->
/// shape 3 (model 0).
Bytes sceneWithTransform(const Pairs& frame, const Pairs& attributes = {}) {
    auto parts = oneModel();
    parts.push_back(transformChunk(0, 1));
    parts.push_back(groupChunk(1, {2}));
    parts.push_back(transformChunk(2, 3, frame, attributes));
    parts.push_back(shapeChunk(3, 0));
    return voxFile(parts);
}

VoxFile parse(std::span<const std::uint8_t> bytes, const VoxReadLimits& limits = {}) {
    return parseVox(bytes, "made.vox", limits);
}

/// Parses `bytes`, expecting an InputError whose one-line message names the file and
/// contains every needle. Returns the message.
std::string expectInputError(std::span<const std::uint8_t> bytes,
                             const std::vector<std::string>& needles,
                             const VoxReadLimits& limits = {}) {
    try {
        parse(bytes, limits);
    } catch (const InputError& e) {
        const std::string what = e.what();
        EXPECT_EQ(what.find('\n'), std::string::npos) << what;
        EXPECT_EQ(what.rfind("made.vox: ", 0), 0u) << what;
        EXPECT_EQ(e.file(), "made.vox");
        for (const auto& n : needles)
            EXPECT_NE(what.find(n), std::string::npos) << "'" << n << "' not in: " << what;
        return what;
    }
    ADD_FAILURE() << "no InputError";
    return {};
}

/// Parses and returns true, or returns false on InputError; anything else escapes and fails.
bool parsesOrInputError(std::span<const std::uint8_t> bytes, const VoxReadLimits& limits = {}) {
    try {
        parse(bytes, limits);
        return true;
    } catch (const InputError& e) {
        const std::string what = e.what();
        EXPECT_EQ(what.find('\n'), std::string::npos) << what;
        EXPECT_EQ(what.rfind("made.vox: ", 0), 0u) << what;
        return false;
    }
}

Mat3i rowsToMat(const std::array<std::array<int, 3>, 3>& rows) {
    Mat3i m(0);
    for (int r = 0; r < 3; ++r)
        for (int c = 0; c < 3; ++c) m[c][r] = rows[std::size_t(r)][std::size_t(c)];
    return m;
}

int det(const Mat3i& m) {
    return m[0][0] * (m[1][1] * m[2][2] - m[2][1] * m[1][2]) -
           m[1][0] * (m[0][1] * m[2][2] - m[2][1] * m[0][2]) +
           m[2][0] * (m[0][1] * m[1][2] - m[1][1] * m[0][2]);
}

/// A deliberately naive walk of MAIN's direct children (no validation): enough to pull raw
/// chunk contents out of a known-good file without going through the reader.
std::map<std::string, std::vector<Bytes>> rawChunks(const Bytes& file) {
    std::map<std::string, std::vector<Bytes>> out;
    for (std::size_t at = 20; at + 12 <= file.size();) {
        const std::string id(file.begin() + std::ptrdiff_t(at),
                             file.begin() + std::ptrdiff_t(at) + 4);
        const auto n = std::size_t(getI32(file, at + 4));
        const auto m = std::size_t(getI32(file, at + 8));
        out[id].emplace_back(file.begin() + std::ptrdiff_t(at + 12),
                             file.begin() + std::ptrdiff_t(at + 12 + n));
        at += 12 + n + m;
    }
    return out;
}

// --- Real files ------------------------------------------------------------------------------

TEST(VoxReader, LoadsEveryRealFileWithTheFactsOfExpectedJson) {
    std::ifstream in(voxPath("expected.json"));
    ASSERT_TRUE(in);
    const auto expected = nlohmann::ordered_json::parse(in);
    int checked = 0;
    for (const auto& [name, facts] : expected.items()) {
        if (!facts.contains("version")) continue; // not_a.vox, default_palette.bytes
        SCOPED_TRACE(name);
        const VoxFile vox = readVoxFile(voxPath(name));
        EXPECT_EQ(vox.version, facts["version"].get<int>());
        ASSERT_EQ(vox.models.size(), facts["models"].get<std::size_t>());
        for (std::size_t i = 0; i < vox.models.size(); ++i) {
            const auto& s = facts["sizes"][i];
            EXPECT_EQ(vox.models[i].dims(),
                      glm::ivec3(s[0].get<int>(), s[1].get<int>(), s[2].get<int>()))
                << "model " << i;
            EXPECT_EQ(vox.models[i].solidCount(), facts["voxels"][i].get<std::size_t>())
                << "model " << i;
        }
        EXPECT_EQ(vox.totalVoxels(), facts["total_voxels"].get<std::size_t>());
        // Raw XYZI colour bytes are stored as is (no off-by-one against the palette).
        int lo = 256, hi = 0;
        for (const auto& m : vox.models)
            for (const std::uint8_t v : m.data())
                if (v) lo = std::min(lo, int(v)), hi = std::max(hi, int(v));
        EXPECT_EQ(lo, facts["color_index_range"][0].get<int>());
        EXPECT_EQ(hi, facts["color_index_range"][1].get<int>());
        std::vector<std::pair<std::string, int>> chunks;
        for (const auto& [id, count] : facts["chunks"].items())
            chunks.emplace_back(id, count.get<int>());
        EXPECT_EQ(vox.chunkCounts, chunks); // same counts, in first-seen order
        EXPECT_EQ(vox.hasPaletteChunk, facts["has_RGBA"].get<bool>());
        if (!facts["has_RGBA"].get<bool>()) {
            EXPECT_EQ(vox.palette, magicaVoxelDefaultPalette());
        }
        const auto anim = facts["ogt_vox_crosscheck"]["anim"].get<std::string>();
        if (anim != "0..30") { // ogt_vox's default when there is no META _anim_range
            ASSERT_TRUE(vox.animRange);
            EXPECT_EQ(std::to_string(vox.animRange->first) + ".." +
                          std::to_string(vox.animRange->second),
                      anim);
        }
        const bool hasSceneGraph = facts["chunks"].contains("nTRN");
        if (hasSceneGraph)
            EXPECT_EQ(vox.instances.size(),
                      std::stoul(facts["ogt_vox_crosscheck"]["instances"].get<std::string>()));
        else
            EXPECT_TRUE(vox.instances.empty());
        ++checked;
    }
    EXPECT_EQ(checked, 12);
}

TEST(VoxReader, InstanceCountsMatchOgtVoxIncludingHiddenAndShared) {
    const std::vector<std::pair<std::string, std::size_t>> cases = {
        {"dot_vox/axes.vox", 10},
        {"opengametools/test_multiple_model_scene.vox", 104},
        {"bevy_vox_scene/test.vox", 11},
        {"vox-reader.js/tree.vox", 3},
        {"blender_magicavoxel/hierarchy.vox", 4},
    };
    for (const auto& [file, count] : cases) {
        const VoxFile vox = readVoxFile(voxPath(file));
        EXPECT_EQ(vox.instances.size(), count) << file;
    }
}

TEST(VoxReader, HiddenNodeHidesBothPathsThroughSharedGroup) {
    // bevy test.vox: transform 13 (_hidden 1) -> dice shape, inside group 7, which is
    // referenced by two transforms named inner-group: 2 hidden dice instances.
    const VoxFile vox = readVoxFile(voxPath("bevy_vox_scene/test.vox"));
    int hidden = 0;
    for (const auto& inst : vox.instances) {
        if (!inst.hidden) continue;
        ++hidden;
        EXPECT_EQ(inst.model, 2);
        EXPECT_EQ(inst.name, "inner-group"); // nearest named transform on the path
    }
    EXPECT_EQ(hidden, 2);
    std::multiset<std::string> names;
    for (const auto& inst : vox.instances) names.insert(inst.name);
    EXPECT_EQ(names.count("floor"), 1u);
    EXPECT_EQ(names.count("cloud"), 2u);
    EXPECT_EQ(names.count("walls"), 2u);
    EXPECT_EQ(names.count("dice"), 2u);
}

TEST(VoxReader, ComposesNestedTransformsParentTimesChild) {
    // hierarchy.vox, decoded by hand: model 0 sits under T2 (_r 17, _t -6 9 16) -> T4
    // (_t -7 10 7) -> T6 (_t 0 0 8). _r 17: row 0 -> column 1 negative, row 1 -> column 0.
    // t = R2 * (t4 + t6) + t2 = R2 * (-7, 10, 15) + (-6, 9, 16) = (-10, -7, 15) + ... .
    const VoxFile vox = readVoxFile(voxPath("blender_magicavoxel/hierarchy.vox"));
    ASSERT_EQ(vox.instances.size(), 4u);
    const Mat3i r17 = rowsToMat({{{0, -1, 0}, {1, 0, 0}, {0, 0, 1}}});
    std::map<int, const VoxInstance*> byModel;
    for (const auto& inst : vox.instances) byModel[inst.model] = &inst;
    ASSERT_EQ(byModel.size(), 4u);
    EXPECT_EQ(byModel[0]->rotation, r17);
    EXPECT_EQ(byModel[0]->translation, glm::ivec3(-16, 2, 31));
    // model 1: T2 -> T4 -> T8 (_t 0 0 -8): R2 * (-7, 10, -1) + t2.
    EXPECT_EQ(byModel[1]->translation, glm::ivec3(-16, 2, 15));
    // model 2: T2 -> T10 (_t 7 -9 -14): R2 * (7, -9, -14) + t2.
    EXPECT_EQ(byModel[2]->translation, glm::ivec3(3, 16, 2));
    // model 3: T12 (_t 15 0 2), no rotation.
    EXPECT_EQ(byModel[3]->rotation, Mat3i(1));
    EXPECT_EQ(byModel[3]->translation, glm::ivec3(15, 0, 2));
}

TEST(VoxReader, AnimatedTransformUsesKeyframeZeroAndRecordsItsFrame) {
    // test_meta_chunk.vox: nTRN 2 has keyframes _f 7 (_t -23 0 20) and _f 16 (_t 29 0 20).
    const VoxFile vox = readVoxFile(voxPath("opengametools/test_meta_chunk.vox"));
    ASSERT_EQ(vox.instances.size(), 1u);
    EXPECT_EQ(vox.instances[0].frameIndex, 7);
    EXPECT_EQ(vox.instances[0].translation, glm::ivec3(-23, 0, 20));
    ASSERT_TRUE(vox.animRange);
    EXPECT_EQ(*vox.animRange, std::make_pair(7, 36));
}

TEST(VoxReader, DefaultPaletteEqualsDotVoxBytes) {
    const Bytes bytes = readBytes(voxPath("dot_vox/default_palette.bytes"));
    ASSERT_EQ(bytes.size(), 1024u);
    const Palette& p = magicaVoxelDefaultPalette();
    EXPECT_EQ(p.colors[0], 0u);
    for (std::size_t k = 0; k < 255; ++k) // entry k is palette index k + 1
        EXPECT_EQ(p.colors[k + 1],
                  packRgba(bytes[4 * k], bytes[4 * k + 1], bytes[4 * k + 2], bytes[4 * k + 3]))
            << "index " << k + 1;
    EXPECT_EQ(readVoxFile(voxPath("mmmm/obj_house7.vox")).palette, p);
}

TEST(VoxReader, RgbaChunkEntryIIsPaletteIndexIPlusOne) {
    const std::string file = voxPath("mmmm/chr_cop1.vox");
    const auto raw = rawChunks(readBytes(file));
    ASSERT_EQ(raw.at("RGBA").size(), 1u);
    const Bytes& rgba = raw.at("RGBA")[0];
    ASSERT_EQ(rgba.size(), 1024u);
    const VoxFile vox = readVoxFile(file);
    EXPECT_EQ(vox.palette.colors[0], 0u);
    for (std::size_t i = 0; i < 255; ++i)
        EXPECT_EQ(vox.palette.colors[i + 1],
                  packRgba(rgba[4 * i], rgba[4 * i + 1], rgba[4 * i + 2], rgba[4 * i + 3]));
}

TEST(VoxReader, SplatterVoxelsMatchHandDecodedXyziBytes) {
    // obj_splatter1.vox, 108 bytes: "VOX " 150 | MAIN 0 88 | SIZE 12 0 (6 7 1) at 20 |
    // XYZI 52 0 at 44 | count 12 at 56 | 12 x (x y z colour) from 60.
    const Bytes b = readBytes(voxPath("mmmm/obj_splatter1.vox"));
    ASSERT_EQ(b.size(), 108u);
    ASSERT_EQ(std::string(b.begin() + 44, b.begin() + 48), "XYZI");
    ASSERT_EQ(getI32(b, 56), 12);
    const VoxFile vox = readVoxFile(voxPath("mmmm/obj_splatter1.vox"));
    ASSERT_EQ(vox.models.size(), 1u);
    const VoxelGrid& g = vox.models[0];
    EXPECT_EQ(g.dims(), glm::ivec3(getI32(b, 32), getI32(b, 36), getI32(b, 40)));
    for (std::size_t i = 0; i < 12; ++i) {
        const std::size_t at = 60 + 4 * i;
        EXPECT_EQ(g.at({b[at], b[at + 1], b[at + 2]}), b[at + 3]) << "voxel " << i;
    }
    EXPECT_EQ(g.at({5, 6, 0}), 16); // the first voxel, read off the hex dump
    EXPECT_EQ(g.at({0, 0, 0}), 16);
    EXPECT_EQ(g.at({1, 0, 0}), 0);
    EXPECT_EQ(g.solidCount(), 12u);
    // No RGBA chunk: index 16 is the default palette's entry 15.
    const Bytes pal = readBytes(voxPath("dot_vox/default_palette.bytes"));
    EXPECT_EQ(vox.palette.colors[16], packRgba(pal[60], pal[61], pal[62], pal[63]));
}

TEST(VoxReader, EveryXyziVoxelOfRealFilesLandsInItsCell) {
    for (const char* name : {"mmmm/chr_cop1.vox", "mmmm/veh_fire.vox"}) {
        SCOPED_TRACE(name);
        const auto raw = rawChunks(readBytes(voxPath(name)));
        const VoxFile vox = readVoxFile(voxPath(name));
        ASSERT_EQ(raw.at("XYZI").size(), vox.models.size());
        for (std::size_t m = 0; m < vox.models.size(); ++m) {
            const Bytes& xyzi = raw.at("XYZI")[m];
            const auto n = std::size_t(getI32(xyzi, 0));
            std::size_t solid = 0;
            for (std::size_t i = 0; i < n; ++i) {
                const std::uint8_t* v = &xyzi[4 + 4 * i];
                EXPECT_EQ(vox.models[m].at({v[0], v[1], v[2]}), v[3]);
                solid += v[3] != 0;
            }
            EXPECT_EQ(vox.models[m].solidCount(), solid);
        }
    }
}

// --- Rotations -------------------------------------------------------------------------------

TEST(VoxRotation, FourIsIdentity) {
    EXPECT_EQ(decodeVoxRotation(4), Mat3i(1));
}

TEST(VoxRotation, DecodesTheSpecExample) {
    // vox-extension (c): R = [0 1 0; 0 0 -1; -1 0 0] is (1<<0)|(2<<2)|(0<<4)|(1<<5)|(1<<6).
    const unsigned bits = (1u << 0) | (2u << 2) | (0u << 4) | (1u << 5) | (1u << 6);
    EXPECT_EQ(decodeVoxRotation(bits), rowsToMat({{{0, 1, 0}, {0, 0, -1}, {-1, 0, 0}}}));
    EXPECT_EQ(*decodeVoxRotation(bits) * glm::ivec3(1, 2, 3), glm::ivec3(2, -3, -1));
}

TEST(VoxRotation, KeepsReflections) {
    const auto m = decodeVoxRotation(4u | 1u << 4); // identity with row 0 negated
    ASSERT_TRUE(m);
    EXPECT_EQ(*m, rowsToMat({{{-1, 0, 0}, {0, 1, 0}, {0, 0, 1}}}));
    EXPECT_EQ(det(*m), -1);
}

TEST(VoxRotation, RejectsEqualIndicesAndIndexThree) {
    EXPECT_FALSE(decodeVoxRotation(0));            // rows 0 and 1 both column 0
    EXPECT_FALSE(decodeVoxRotation(1u | 1u << 2)); // both column 1
    EXPECT_FALSE(decodeVoxRotation(3u | 1u << 2)); // row 0 column 3
    EXPECT_FALSE(decodeVoxRotation(0u | 3u << 2)); // row 1 column 3
    // Exactly the 48 signed permutation matrices among the 128 7-bit values, all distinct.
    std::set<std::vector<int>> seen;
    for (unsigned bits = 0; bits < 128; ++bits) {
        const auto m = decodeVoxRotation(bits);
        const unsigned a = bits & 3u, b = (bits >> 2) & 3u;
        EXPECT_EQ(bool(m), a != 3 && b != 3 && a != b) << bits;
        if (!m) continue;
        EXPECT_EQ(std::abs(det(*m)), 1) << bits;
        std::vector<int> flat;
        for (int c = 0; c < 3; ++c)
            for (int r = 0; r < 3; ++r) flat.push_back((*m)[c][r]);
        seen.insert(flat);
    }
    EXPECT_EQ(seen.size(), 48u);
}

TEST(VoxRotation, FileRotationsReachInstancesWithReflectionsKept) {
    const VoxFile vox = parse(sceneWithTransform({{"_r", "20"}, {"_t", "1 2 3"}}));
    ASSERT_EQ(vox.instances.size(), 1u);
    EXPECT_EQ(vox.instances[0].rotation, rowsToMat({{{-1, 0, 0}, {0, 1, 0}, {0, 0, 1}}}));
    EXPECT_EQ(vox.instances[0].translation, glm::ivec3(1, 2, 3));
    // tree.vox: _r 17 and 33 (bit 5: row 1 negative).
    const VoxFile tree = readVoxFile(voxPath("vox-reader.js/tree.vox"));
    ASSERT_EQ(tree.instances.size(), 3u);
    EXPECT_EQ(tree.instances[0].rotation, rowsToMat({{{0, -1, 0}, {1, 0, 0}, {0, 0, 1}}}));
    EXPECT_EQ(tree.instances[1].rotation, rowsToMat({{{0, 1, 0}, {-1, 0, 0}, {0, 0, 1}}}));
    EXPECT_EQ(tree.instances[1].translation, glm::ivec3(-10, -11, 128));
}

TEST(VoxRotation, RejectsInvalidRotationStringsInFiles) {
    expectInputError(sceneWithTransform({{"_r", "0"}}), {"nTRN node 2", "_r 0"});
    expectInputError(sceneWithTransform({{"_r", "7"}}), {"nTRN node 2", "_r 7"});
    expectInputError(sceneWithTransform({{"_r", "300"}}), {"nTRN node 2", "_r"});
    expectInputError(sceneWithTransform({{"_r", "4x"}}), {"nTRN node 2", "_r"});
}

// --- Scene graph -----------------------------------------------------------------------------

TEST(VoxSceneGraph, SharedNodeYieldsOneInstancePerPath) {
    auto parts = oneModel();
    parts.push_back(transformChunk(0, 1));
    parts.push_back(groupChunk(1, {2, 3}));
    parts.push_back(transformChunk(2, 4, {{"_t", "10 0 0"}}, {{"_name", "a"}}));
    parts.push_back(transformChunk(3, 4, {{"_t", "-10 0 0"}}, {{"_name", "b"}}));
    parts.push_back(groupChunk(4, {5, 6}));
    parts.push_back(transformChunk(5, 7, {{"_t", "0 1 0"}}));
    parts.push_back(transformChunk(6, 7, {{"_t", "0 0 1"}}, {{"_name", "c"}}));
    parts.push_back(shapeChunk(7, 0));
    const VoxFile vox = parse(voxFile(parts));
    ASSERT_EQ(vox.instances.size(), 4u);
    std::set<std::pair<std::string, std::array<int, 3>>> got;
    for (const auto& i : vox.instances)
        got.insert({i.name, {i.translation.x, i.translation.y, i.translation.z}});
    const std::set<std::pair<std::string, std::array<int, 3>>> want = {
        {"a", {10, 1, 0}}, {"c", {10, 0, 1}}, {"b", {-10, 1, 0}}, {"c", {-10, 0, 1}}};
    EXPECT_EQ(got, want);
}

TEST(VoxSceneGraph, HiddenLayerHidesItsInstances) {
    auto parts = oneModel();
    parts.push_back(transformChunk(0, 1));
    parts.push_back(groupChunk(1, {2, 4}));
    parts.push_back(transformChunk(2, 3, {}, {}, /*layer*/ 1));
    parts.push_back(shapeChunk(3, 0));
    parts.push_back(transformChunk(4, 3, {}, {}, /*layer*/ 0));
    parts.push_back(layerChunk(0, {{"_hidden", "0"}}));
    parts.push_back(layerChunk(1, {{"_hidden", "1"}}));
    const VoxFile vox = parse(voxFile(parts));
    ASSERT_EQ(vox.instances.size(), 2u);
    EXPECT_TRUE(vox.instances[0].hidden);
    EXPECT_FALSE(vox.instances[1].hidden);
}

TEST(VoxSceneGraph, RejectsCycles) {
    auto parts = oneModel();
    parts.push_back(transformChunk(0, 1));
    parts.push_back(groupChunk(1, {2}));
    parts.push_back(transformChunk(2, 1)); // back to the group
    expectInputError(voxFile(parts), {"nTRN node 2", "cycle"});

    auto self = oneModel();
    self.push_back(transformChunk(0, 1));
    self.push_back(groupChunk(1, {1}));
    expectInputError(voxFile(self), {"nGRP node 1", "cycle"});

    auto root = oneModel();
    root.push_back(transformChunk(0, 0));
    expectInputError(voxFile(root), {"nTRN node 0", "cycle"});
}

TEST(VoxSceneGraph, RejectsDanglingAndMissingNodes) {
    auto dangling = oneModel();
    dangling.push_back(transformChunk(0, 1));
    dangling.push_back(groupChunk(1, {2, 99}));
    dangling.push_back(transformChunk(2, 3));
    dangling.push_back(shapeChunk(3, 0));
    expectInputError(voxFile(dangling), {"nGRP node 1", "child node 99 does not exist"});

    auto noRoot = oneModel();
    noRoot.push_back(groupChunk(1, {}));
    expectInputError(voxFile(noRoot), {"scene graph", "no root node 0"});

    auto badModel = oneModel();
    badModel.push_back(transformChunk(0, 1));
    badModel.push_back(shapeChunk(1, 1));
    expectInputError(voxFile(badModel), {"nSHP node 1", "model id 1", "1 models"});

    auto twice = oneModel();
    twice.push_back(transformChunk(0, 1));
    twice.push_back(shapeChunk(1, 0));
    twice.push_back(shapeChunk(1, 0));
    expectInputError(voxFile(twice), {"nSHP node 1", "defined twice"});

    auto negative = oneModel();
    negative.push_back(transformChunk(-3, 1));
    expectInputError(voxFile(negative), {"nTRN[0]", "negative node id"});
}

TEST(VoxSceneGraph, RejectsTranslationsThatOverflowInt) {
    expectInputError(sceneWithTransform({{"_t", "2147483648 0 0"}}), {"nTRN node 2", "_t"});
    expectInputError(sceneWithTransform({{"_t", "1 2"}}), {"nTRN node 2", "_t"});
    expectInputError(sceneWithTransform({{"_t", "nan 0 0"}}), {"nTRN node 2", "_t"});
    // Each fits, the sum does not.
    auto parts = oneModel();
    parts.push_back(transformChunk(0, 1, {{"_t", "2147483647 0 0"}}));
    parts.push_back(groupChunk(1, {2}));
    parts.push_back(transformChunk(2, 3, {{"_t", "1 0 0"}}));
    parts.push_back(shapeChunk(3, 0));
    expectInputError(voxFile(parts), {"nTRN node 2", "overflows"});
    // The extremes themselves are fine.
    const VoxFile ok = parse(sceneWithTransform({{"_t", "-2147483648 2147483647 0"}}));
    EXPECT_EQ(ok.instances.at(0).translation, glm::ivec3(-2147483647 - 1, 2147483647, 0));
}

TEST(VoxSceneGraph, BoundsInstancingExplosion) {
    // 30 levels of "group -> two transforms -> next group": 2^30 paths in ~1 KB, ending in an
    // empty group, so no instance is ever produced and only the visit bound can stop it.
    auto parts = oneModel();
    parts.push_back(transformChunk(0, 1));
    const int levels = 30;
    for (int l = 0; l < levels; ++l) {
        const int g = 1 + 3 * l;
        parts.push_back(groupChunk(g, {g + 1, g + 2}));
        parts.push_back(transformChunk(g + 1, g + 3));
        parts.push_back(transformChunk(g + 2, g + 3));
    }
    parts.push_back(groupChunk(1 + 3 * levels, {}));
    expectInputError(voxFile(parts), {"scene graph", "node visits"});
    parts.back() = shapeChunk(1 + 3 * levels, 0); // now every path is an instance
    expectInputError(voxFile(parts), {"scene graph", "instances"});

    VoxReadLimits limits;
    limits.maxInstances = 3;
    auto four = oneModel();
    four.push_back(transformChunk(0, 1));
    four.push_back(groupChunk(1, {2, 2, 2, 2}));
    four.push_back(transformChunk(2, 3));
    four.push_back(shapeChunk(3, 0));
    EXPECT_EQ(parse(voxFile(four)).instances.size(), 4u);
    expectInputError(voxFile(four), {"scene graph", "more than 3 instances"}, limits);
}

// --- Malformed files -------------------------------------------------------------------------

TEST(VoxMalformed, RejectsBadMagic) {
    const std::string file = voxPath("dot_vox/not_a.vox");
    try {
        readVoxFile(file);
        ADD_FAILURE() << "not_a.vox parsed";
    } catch (const InputError& e) {
        const std::string what = e.what();
        EXPECT_EQ(what.find('\n'), std::string::npos);
        EXPECT_NE(what.find(file), std::string::npos) << what;
        EXPECT_NE(what.find("not a MagicaVoxel .vox file"), std::string::npos) << what;
        EXPECT_NE(what.find("DOOD"), std::string::npos) << what;
    }
    Bytes binary = voxFile(oneModel());
    binary[0] = 0;
    binary[1] = '\n';
    expectInputError(binary, {"header", "not a MagicaVoxel .vox file", "\\x00\\x0a"});
}

TEST(VoxMalformed, RejectsMissingFileAndTruncatedHeader) {
    EXPECT_THROW(readVoxFile(voxPath("no_such_file.vox")), InputError);
    EXPECT_THROW(readVoxFile(voxPath("mmmm")), InputError); // a directory
    expectInputError(Bytes{}, {"header", "truncated"});
    expectInputError(Bytes{'V', 'O', 'X', ' ', 150, 0}, {"header", "truncated"});
    expectInputError(Bytes{'V', 'O', 'X', ' ', 150, 0, 0, 0, 'M', 'A', 'I'}, {"truncated"});
}

TEST(VoxMalformed, EveryStrictPrefixOfARealFileThrows) {
    // MAIN declares the length of everything, so no strict prefix is a complete file.
    for (const char* name : {"mmmm/obj_splatter1.vox", "blender_magicavoxel/hierarchy.vox"}) {
        SCOPED_TRACE(name);
        const Bytes full = readBytes(voxPath(name));
        EXPECT_TRUE(parsesOrInputError(full));
        for (std::size_t n = 0; n < full.size(); ++n)
            ASSERT_FALSE(parsesOrInputError(std::span(full).first(n)))
                << "prefix of " << n << " bytes parsed";
    }
}

TEST(VoxMalformed, TruncatingInsideChunksNeverCrashes) {
    // Same prefixes, but with MAIN's children size patched to fit, so the cut lands inside
    // a child chunk (or, at a chunk boundary, leaves a shorter but valid file).
    for (const char* name : {"mmmm/obj_splatter1.vox", "blender_magicavoxel/hierarchy.vox",
                             "dot_vox/single-voxel-with-material.vox"}) {
        SCOPED_TRACE(name);
        const Bytes full = readBytes(voxPath(name));
        const std::int32_t mainContent = getI32(full, 12);
        ASSERT_EQ(mainContent, 0);
        int parsed = 0, rejected = 0;
        Bytes patched = full;
        for (std::size_t n = 20; n < full.size(); ++n) {
            const auto children = std::uint32_t(n - 20);
            for (int i = 0; i < 4; ++i)
                patched[16 + std::size_t(i)] = std::uint8_t(children >> (8 * i));
            (parsesOrInputError(std::span(patched).first(n)) ? parsed : rejected)++;
        }
        EXPECT_GT(rejected, parsed);
    }
}

TEST(VoxMalformed, RandomByteCorruptionOnlyEverThrowsInputError) {
    const Bytes full = readBytes(voxPath("blender_magicavoxel/hierarchy.vox"));
    std::mt19937 rng(12345);
    const std::uint8_t interesting[] = {0x00, 0x01, 0x7f, 0x80, 0xff, 0xfe, 0x10, 0x03};
    VoxReadLimits limits;
    limits.maxVoxelCells = 1 << 22; // keep each attempt cheap
    for (int round = 0; round < 3000; ++round) {
        Bytes b = full;
        const int edits = 1 + int(rng() % 4);
        for (int e = 0; e < edits; ++e) {
            const std::size_t at = 8 + rng() % (b.size() - 8);
            b[at] = rng() % 2 ? interesting[rng() % std::size(interesting)] : std::uint8_t(rng());
        }
        parsesOrInputError(b, limits);
    }
}

TEST(VoxMalformed, RejectsChunkOverrunningParent) {
    // SIZE claims 100 content bytes; the file has them (padding after MAIN) but MAIN does not.
    Bytes size = sizeChunk(2, 2, 2);
    size[4] = 100;
    Bytes file = voxFile({size});
    file.resize(file.size() + 200, 0);
    expectInputError(file, {"SIZE[0]", "overrun MAIN", "at byte 20"});
    // Children bytes count too.
    Bytes withChildren = chunk("XXXX", {}, Bytes(8, 0));
    withChildren[8] = 50;
    expectInputError(voxFile({withChildren}), {"XXXX[0]", "overrun MAIN"});
}

TEST(VoxMalformed, RejectsChunkOverrunningFile) {
    Bytes file = voxFile(oneModel());
    file.pop_back();
    expectInputError(file, {"MAIN[0]", "overrun the file"});
    Bytes huge = voxFile(oneModel());
    for (int i = 0; i < 4; ++i) huge[16 + std::size_t(i)] = 0xff; // children = -1
    expectInputError(huge, {"MAIN[0]", "negative children size -1"});
    huge[19] = 0x7f; // children = INT32_MAX
    expectInputError(huge, {"MAIN[0]", "overrun the file"});
}

TEST(VoxMalformed, RejectsNegativeChunkSizes) {
    Bytes s = sizeChunk(2, 2, 2);
    for (int i = 0; i < 4; ++i) s[4 + std::size_t(i)] = 0xff;
    expectInputError(voxFile({s}), {"SIZE[0]", "negative content size -1"});
}

TEST(VoxMalformed, RejectsTruncatedChunkHeaderAndContent) {
    const Bytes tail = {'R', 'G', 'B'};
    Bytes patched = voxFile({oneModel()[0], oneModel()[1], tail});
    expectInputError(patched, {"MAIN", "truncated chunk header"});
    expectInputError(voxFile({chunk("SIZE", Bytes(8, 1)), xyziChunk({})}),
                     {"SIZE[0]", "truncated", "size z"});
    expectInputError(voxFile({oneModel()[0], oneModel()[1], chunk("RGBA", Bytes(1000, 1))}),
                     {"RGBA[0]", "1024"});
}

TEST(VoxMalformed, RejectsVoxelsOutsideTheModelSize) {
    expectInputError(voxFile({sizeChunk(2, 3, 4), xyziChunk({{1, 2, 3, 5}, {0, 3, 0, 5}})}),
                     {"XYZI[0]", "voxel 1", "(0, 3, 0)", "2x3x4"});
    expectInputError(voxFile({sizeChunk(2, 3, 4), xyziChunk({{255, 0, 0, 5}})}),
                     {"XYZI[0]", "voxel 0"});
    // The second model is checked against its own size.
    expectInputError(voxFile({sizeChunk(8, 8, 8), xyziChunk({{7, 7, 7, 1}}), sizeChunk(4, 4, 4),
                              xyziChunk({{7, 0, 0, 1}})}),
                     {"XYZI[1]", "voxel 0"});
}

TEST(VoxMalformed, RejectsXyziBeforeSizeAndSizeWithoutXyzi) {
    expectInputError(voxFile({xyziChunk({{0, 0, 0, 1}}), sizeChunk(1, 1, 1)}),
                     {"XYZI[0]", "before any SIZE"});
    expectInputError(voxFile({sizeChunk(1, 1, 1), sizeChunk(1, 1, 1), xyziChunk({})}),
                     {"SIZE[0]", "another SIZE"});
    expectInputError(voxFile({sizeChunk(1, 1, 1), xyziChunk({}), sizeChunk(1, 1, 1)}),
                     {"SIZE[1]", "not followed by an XYZI"});
}

TEST(VoxMalformed, RejectsXyziCountLargerThanTheChunk) {
    Bytes x = xyziChunk({{0, 0, 0, 1}});
    x[12] = 2; // count 2, one voxel present
    expectInputError(voxFile({sizeChunk(2, 2, 2), x}), {"XYZI[0]", "voxel count 2"});
    for (int i = 0; i < 4; ++i) x[12 + std::size_t(i)] = i == 3 ? 0x7f : 0xff;
    expectInputError(voxFile({sizeChunk(2, 2, 2), x}), {"XYZI[0]", "voxel count 2147483647"});
    x[15] = 0x80; // INT32_MIN
    expectInputError(voxFile({sizeChunk(2, 2, 2), x}), {"XYZI[0]", "negative"});
}

TEST(VoxMalformed, RejectsZeroNegativeAndOversizedModelSizes) {
    for (const glm::ivec3 s : {glm::ivec3(0, 1, 1), glm::ivec3(1, -1, 1), glm::ivec3(1, 1, 257),
                               glm::ivec3(-2147483647 - 1, 1, 1), glm::ivec3(1 << 20, 1, 1)})
        expectInputError(voxFile({sizeChunk(s.x, s.y, s.z), xyziChunk({})}),
                         {"SIZE[0]", "outside 1..256"});
    const VoxFile ok = parse(voxFile({sizeChunk(256, 1, 2), xyziChunk({{255, 0, 1, 9}})}));
    EXPECT_EQ(ok.models[0].dims(), glm::ivec3(256, 1, 2));
    EXPECT_EQ(ok.models[0].at({255, 0, 1}), 9);
}

TEST(VoxMalformed, BoundsTotalGridMemory) {
    VoxReadLimits limits;
    limits.maxVoxelCells = 1000;
    const Bytes file =
        voxFile({sizeChunk(8, 8, 8), xyziChunk({}), sizeChunk(8, 8, 8), xyziChunk({})});
    expectInputError(file, {"XYZI[1]", "limit of 1000 voxel cells"}, limits);
    limits.maxVoxelCells = 1024;
    EXPECT_EQ(parse(file, limits).models.size(), 2u);
}

TEST(VoxMalformed, RejectsFileWithoutModels) {
    Bytes rgba(1024, 7);
    expectInputError(voxFile({chunk("RGBA", rgba)}), {"MAIN", "no models"});
    expectInputError(voxFile({}), {"MAIN", "no models"});
}

TEST(VoxMalformed, RejectsNonTerminatingDictsAndStrings) {
    // A key whose length runs past the chunk.
    Bytes c;
    putI32(c, 0);
    putI32(c, 1);
    putI32(c, 1000);
    c.insert(c.end(), {'_', 'n', 'a', 'm', 'e', '!'});
    auto parts = oneModel();
    parts.push_back(chunk("nTRN", c));
    expectInputError(voxFile(parts), {"nTRN node 0", "key length 1000", "only 6 remain"});
    // A pair count no chunk could hold.
    Bytes d;
    putI32(d, 0);
    putI32(d, 0x7fffffff);
    parts.back() = chunk("nTRN", d);
    expectInputError(voxFile(parts), {"nTRN node 0", "pair count 2147483647"});
    // A negative string length.
    Bytes e;
    putI32(e, 0);
    putI32(e, 1);
    putI32(e, -5);
    putI32(e, 0);
    parts.back() = chunk("nTRN", e);
    expectInputError(voxFile(parts), {"nTRN node 0", "negative"});
    // Huge child and frame counts.
    Bytes g;
    putI32(g, 1);
    putDict(g, {});
    putI32(g, 1 << 30);
    parts.back() = chunk("nGRP", g);
    expectInputError(voxFile(parts), {"nGRP node 1", "child count 1073741824"});
    // META with a malformed range.
    Bytes m;
    putDict(m, {{"_anim_range", "7"}});
    parts.back() = chunk("META", m);
    expectInputError(voxFile(parts), {"META[0]", "_anim_range '7'"});
}

TEST(VoxReader, TreatsPaletteIndexZeroAsEmpty) {
    const VoxFile vox = parse(
        voxFile({sizeChunk(3, 1, 1), xyziChunk({{0, 0, 0, 0}, {1, 0, 0, 255}, {2, 0, 0, 0}})}));
    EXPECT_EQ(vox.models[0].solidCount(), 1u);
    EXPECT_EQ(vox.models[0].at({1, 0, 0}), 255);
    EXPECT_EQ(vox.models[0].at({0, 0, 0}), 0);
}

TEST(VoxReader, AcceptsUnknownVersionsAndSkipsUnknownChunks) {
    auto parts = oneModel();
    parts.insert(parts.begin(), chunk("PACK", {1, 0, 0, 0}));
    parts.push_back(chunk("IMAP", Bytes(256, 3)));
    parts.push_back(chunk("zZz\x01", Bytes(5, 9), chunk("SIZE", Bytes(2, 0)))); // odd child
    parts.push_back(chunk("MATL", Bytes(3, 0)));
    const VoxFile vox = parse(voxFile(parts, 9999));
    EXPECT_EQ(vox.version, 9999);
    ASSERT_EQ(vox.models.size(), 1u);
    const std::vector<std::pair<std::string, int>> counts = {
        {"MAIN", 1}, {"PACK", 1},     {"SIZE", 1}, {"XYZI", 1},
        {"IMAP", 1}, {"zZz\\x01", 1}, {"MATL", 1}};
    EXPECT_EQ(vox.chunkCounts, counts);
    EXPECT_FALSE(vox.hasPaletteChunk);
    EXPECT_TRUE(vox.instances.empty());
}

// --- voxtier info ----------------------------------------------------------------------------

using RunResult = test::CliRun;
using test::runCli;

TEST(VoxInfoCli, PrintsModelSizesAndCounts) {
    const RunResult r = runCli("info '" + voxPath("bevy_vox_scene/test.vox") + "'");
    ASSERT_EQ(r.status, 0) << r.err;
    EXPECT_TRUE(r.err.empty()) << r.err;
    for (const char* needle :
         {"version:      150", "models:       4", "50x128x40, 6400 voxels", "40x40x20, 5286 voxels",
          "total voxels: 12030", "RGBA chunk", "MATL 256", "instances:    11 (2 hidden)"})
        EXPECT_NE(r.out.find(needle), std::string::npos) << needle << "\n" << r.out;

    const RunResult def = runCli("info '" + voxPath("mmmm/obj_splatter1.vox") + "'");
    ASSERT_EQ(def.status, 0) << def.err;
    EXPECT_NE(def.out.find("6x7x1, 12 voxels"), std::string::npos) << def.out;
    EXPECT_NE(def.out.find("default palette"), std::string::npos) << def.out;
}

TEST(VoxInfoCli, JsonFormIsMachineReadable) {
    const RunResult r =
        runCli("info --json '" + voxPath("opengametools/test_meta_chunk.vox") + "'");
    ASSERT_EQ(r.status, 0) << r.err;
    const auto j = nlohmann::json::parse(r.out);
    EXPECT_EQ(j["version"], 200);
    ASSERT_EQ(j["models"].size(), 1u);
    EXPECT_EQ(j["models"][0]["size"], nlohmann::json({40, 40, 40}));
    EXPECT_EQ(j["models"][0]["voxels"], 64000);
    EXPECT_EQ(j["total_voxels"], 64000);
    EXPECT_EQ(j["palette"], "RGBA chunk");
    EXPECT_EQ(j["chunks"]["MATL"], 256);
    EXPECT_EQ(j["instances"], 1);
    EXPECT_EQ(j["hidden_instances"], 0);
    EXPECT_EQ(j["anim_range"], nlohmann::json({7, 36}));
}

TEST(VoxInfoCli, BadFileExitsNonZeroWithOneLineOnStderr) {
    const std::string file = voxPath("dot_vox/not_a.vox");
    const RunResult r = runCli("info '" + file + "'");
    EXPECT_NE(r.status, 0);
    EXPECT_TRUE(r.out.empty()) << r.out;
    ASSERT_FALSE(r.err.empty());
    EXPECT_EQ(r.err.find('\n'), r.err.size() - 1) << r.err; // exactly one line
    EXPECT_NE(r.err.find(file), std::string::npos) << r.err;
    EXPECT_NE(r.err.find("not a MagicaVoxel .vox file"), std::string::npos) << r.err;
}

} // namespace
} // namespace voxtier
