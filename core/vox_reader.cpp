// MagicaVoxel .vox reader, written from ephtracy/voxel-model's MagicaVoxel-file-format-vox.txt
// and -vox-extension.txt. The file is untrusted: every read goes through a bounds-checked
// cursor limited to the enclosing chunk, every count is checked against the bytes that remain
// before anything is allocated from it, and the scene graph is walked iteratively with cycle
// detection and a work bound, so malformed input ends in an InputError and nothing else.
#include "core/vox_reader.hpp"

#include "core/error.hpp"

#include <charconv>
#include <cstring>
#include <fstream>
#include <limits>
#include <string_view>
#include <unordered_map>

namespace voxtier {

std::size_t VoxFile::totalVoxels() const {
    std::size_t n = 0;
    for (const auto& m : models) n += m.solidCount();
    return n;
}

std::optional<glm::mat<3, 3, int>> decodeVoxRotation(unsigned bits) {
    const unsigned row0 = bits & 3u;
    const unsigned row1 = (bits >> 2) & 3u;
    if (row0 == 3 || row1 == 3 || row0 == row1) return std::nullopt;
    const unsigned column[3] = {row0, row1, 3u - row0 - row1};
    glm::mat<3, 3, int> m(0);
    for (unsigned row = 0; row < 3; ++row)
        m[int(column[row])][int(row)] = (bits >> (4 + row)) & 1u ? -1 : 1;
    return m;
}

namespace {

using Mat3i = glm::mat<3, 3, int>;
using Dict = std::vector<std::pair<std::string, std::string>>;

/// Bytes taken from the file, fit for a one-line message: printable ASCII as is (except the
/// backslash, so the escaping stays unambiguous), everything else as \xNN, long values cut.
std::string printable(std::string_view s, std::size_t maxLen = 48) {
    static constexpr char hex[] = "0123456789abcdef";
    std::string out;
    for (std::size_t i = 0; i < s.size() && i < maxLen; ++i) {
        const auto c = static_cast<unsigned char>(s[i]);
        if (c >= 0x20 && c < 0x7f && c != '\\') {
            out += char(c);
        } else {
            out += "\\x";
            out += hex[c >> 4];
            out += hex[c & 15u];
        }
    }
    if (s.size() > maxLen) out += "...";
    return out;
}

std::string quote(std::string_view s) {
    return "'" + printable(s) + "'";
}

const std::string* findKey(const Dict& dict, std::string_view key) {
    // MagicaVoxel never repeats a key; if a file does, the last value wins (as in a map
    // filled in file order).
    const std::string* found = nullptr;
    for (const auto& [k, v] : dict)
        if (k == key) found = &v;
    return found;
}

/// Whitespace-separated decimal int32s; nullopt unless the string holds exactly `count` of
/// them. from_chars rejects overflow, so a huge `_t` cannot wrap around.
std::optional<std::vector<std::int32_t>> parseInts(std::string_view s, std::size_t count) {
    std::vector<std::int32_t> values;
    const char* p = s.data();
    const char* end = s.data() + s.size();
    while (true) {
        while (p != end && (*p == ' ' || *p == '\t')) ++p;
        if (p == end) break;
        if (values.size() == count) return std::nullopt;
        std::int32_t v = 0;
        const auto [next, ec] = std::from_chars(p, end, v);
        if (ec != std::errc{}) return std::nullopt;
        if (next != end && *next != ' ' && *next != '\t') return std::nullopt;
        values.push_back(v);
        p = next;
    }
    if (values.size() != count) return std::nullopt;
    return values;
}

std::optional<std::int32_t> parseInt(std::string_view s) {
    auto v = parseInts(s, 1);
    if (!v) return std::nullopt;
    return (*v)[0];
}

/// A bounds-checked little-endian reader over [begin, end) of the file. `field` names the
/// chunk in errors; offsets in messages are file offsets, so they can be checked in a hex dump.
class Cursor {
  public:
    Cursor(std::span<const std::uint8_t> file, std::size_t begin, std::size_t end,
           const std::string& source, std::string field, const char* scope)
        : file_(file), pos_(begin), end_(end), source_(source), field_(std::move(field)),
          scope_(scope) {}

    std::size_t offset() const { return pos_; }
    std::size_t remaining() const { return end_ - pos_; }
    void setField(std::string field) { field_ = std::move(field); }
    const std::string& field() const { return field_; }

    [[noreturn]] void fail(const std::string& reason) const {
        throw InputError(source_, field_, reason);
    }

    void need(std::size_t n, std::string_view what) const {
        if (n > remaining())
            fail("truncated: " + std::string(what) + " needs " + std::to_string(n) +
                 " bytes at byte " + std::to_string(pos_) + ", only " +
                 std::to_string(remaining()) + " remain in the " + scope_);
    }

    std::int32_t i32(std::string_view what) {
        need(4, what);
        const std::uint8_t* b = file_.data() + pos_;
        const std::uint32_t v = std::uint32_t(b[0]) | std::uint32_t(b[1]) << 8 |
                                std::uint32_t(b[2]) << 16 | std::uint32_t(b[3]) << 24;
        pos_ += 4;
        return static_cast<std::int32_t>(v); // two's complement by definition since C++20
    }

    std::uint8_t u8() {
        need(1, "a byte");
        return file_[pos_++];
    }

    /// A count of items that each take at least `minItemBytes`: bounded by what remains, so
    /// nothing is ever reserved or looped over from an unchecked number.
    std::size_t count(std::string_view what, std::size_t minItemBytes) {
        const std::size_t at = pos_;
        const std::int32_t n = i32(what);
        if (n < 0)
            fail(std::string(what) + " is negative (" + std::to_string(n) + ") at byte " +
                 std::to_string(at));
        if (std::size_t(n) > remaining() / minItemBytes)
            fail(std::string(what) + " " + std::to_string(n) + " at byte " + std::to_string(at) +
                 " needs at least " + std::to_string(std::size_t(n) * minItemBytes) +
                 " bytes, only " + std::to_string(remaining()) + " remain in the " + scope_);
        return std::size_t(n);
    }

    std::string string(std::string_view what) {
        const std::size_t n = count(std::string(what) + " length", 1);
        std::string s(reinterpret_cast<const char*>(file_.data() + pos_), n);
        pos_ += n;
        return s;
    }

    Dict dict(std::string_view what) {
        // Each pair holds two length-prefixed strings, so at least 8 bytes.
        const std::size_t n = count(std::string(what) + " pair count", 8);
        Dict d;
        d.reserve(n);
        for (std::size_t i = 0; i < n; ++i) {
            std::string key = string(std::string(what) + " key");
            std::string value = string(std::string(what) + " value of " + quote(key));
            d.emplace_back(std::move(key), std::move(value));
        }
        return d;
    }

  private:
    std::span<const std::uint8_t> file_;
    std::size_t pos_, end_;
    const std::string& source_;
    std::string field_;
    const char* scope_;
};

struct SceneNode {
    enum class Kind { Transform, Group, Shape };
    Kind kind = Kind::Transform;
    std::string label; ///< "nTRN node 5", for messages
    bool hidden = false;
    // Transform (frame 0 of its keyframes; see VoxInstance::frameIndex).
    std::string name;
    std::int32_t child = -1;
    std::int32_t layer = -1;
    Mat3i rotation{1};
    glm::ivec3 translation{0};
    std::optional<int> frame;
    // Group.
    std::vector<std::int32_t> children;
    // Shape: the first model; a shape without models draws nothing.
    std::optional<std::int32_t> model;
};

/// Accumulated state of one path from the root, after applying the node it belongs to.
struct PathState {
    Mat3i rotation{1};
    std::int64_t translation[3] = {0, 0, 0};
    bool hidden = false;
    const std::string* name = nullptr;
    int frame = 0;
};

class Parser {
  public:
    Parser(std::span<const std::uint8_t> bytes, const std::string& source,
           const VoxReadLimits& limits)
        : bytes_(bytes), limits_(limits) {
        out_.source = source;
    }

    VoxFile run();

  private:
    [[noreturn]] void fail(const std::string& field, const std::string& reason) const {
        throw InputError(out_.source, field, reason);
    }

    /// Records the chunk in chunkCounts and returns its label, e.g. "XYZI[2]".
    std::string countChunk(std::string_view rawId);
    void parseChunk(const std::string& id, const std::string& label, std::size_t begin,
                    std::size_t end);
    void parseSize(Cursor& c);
    void parseXyzi(Cursor& c);
    void parseRgba(Cursor& c);
    void parseTransform(Cursor& c);
    void parseGroup(Cursor& c);
    void parseShape(Cursor& c);
    void parseLayer(Cursor& c);
    void parseMeta(Cursor& c);
    std::int32_t readNodeId(Cursor& c, const char* kind);
    void addNode(std::int32_t id, SceneNode node, const Cursor& c);
    void flattenSceneGraph();

    std::span<const std::uint8_t> bytes_;
    const VoxReadLimits& limits_;
    VoxFile out_;
    std::unordered_map<std::string, std::size_t> chunkSlot_; ///< id -> index in chunkCounts
    std::optional<glm::ivec3> pendingSize_;
    std::string pendingSizeLabel_;
    std::size_t voxelCells_ = 0;
    std::vector<SceneNode> nodes_;
    std::unordered_map<std::int32_t, std::size_t> nodeIndex_;
    std::unordered_map<std::int32_t, bool> layerHidden_;
};

std::string Parser::countChunk(std::string_view rawId) {
    const std::string id = printable(rawId);
    auto [it, inserted] = chunkSlot_.try_emplace(id, out_.chunkCounts.size());
    if (inserted) out_.chunkCounts.emplace_back(id, 0);
    const int index = out_.chunkCounts[it->second].second++;
    return id + "[" + std::to_string(index) + "]";
}

VoxFile Parser::run() {
    const std::size_t size = bytes_.size();
    if (size < 8)
        fail("header",
             "truncated: the file has " + std::to_string(size) + " bytes, a .vox header needs 8");
    if (std::memcmp(bytes_.data(), "VOX ", 4) != 0)
        fail("header", "not a MagicaVoxel .vox file (magic " +
                           quote({reinterpret_cast<const char*>(bytes_.data()), 4}) +
                           ", expected 'VOX ')");
    Cursor header(bytes_, 4, size, out_.source, "header", "file");
    // Any version is accepted: 150 and 200 differ only in which chunks appear, and the
    // structure below is checked chunk by chunk anyway.
    out_.version = header.i32("version");

    // Chunks are walked with explicit offsets (not recursion): only MAIN's direct children
    // carry data; children of any other chunk are bounds-checked and skipped.
    struct Header {
        std::string id, label;
        std::size_t contentBegin, contentEnd, childrenEnd;
    };
    auto readHeader = [&](std::size_t at, std::size_t parentEnd, const char* parent) -> Header {
        const std::size_t left = parentEnd - at;
        if (left < 12) {
            const std::string field =
                left >= 4 ? printable({reinterpret_cast<const char*>(bytes_.data() + at), 4})
                          : std::string(parent);
            fail(field, "truncated chunk header at byte " + std::to_string(at) +
                            ": 12 bytes needed, only " + std::to_string(left) + " remain in " +
                            parent);
        }
        Header h;
        h.id.assign(reinterpret_cast<const char*>(bytes_.data() + at), 4);
        h.label = countChunk(h.id);
        Cursor c(bytes_, at + 4, at + 12, out_.source, h.label, "chunk header");
        const std::int32_t content = c.i32("content size");
        const std::int32_t children = c.i32("children size");
        if (content < 0 || children < 0)
            fail(h.label, "negative " + std::string(content < 0 ? "content" : "children") +
                              " size " + std::to_string(content < 0 ? content : children) +
                              " in the chunk header at byte " + std::to_string(at));
        const std::size_t body = std::size_t(content) + std::size_t(children);
        if (body > left - 12)
            fail(h.label, "content (" + std::to_string(content) + " bytes) and children (" +
                              std::to_string(children) + " bytes) of the chunk at byte " +
                              std::to_string(at) + " overrun " + parent + ", which has " +
                              std::to_string(left - 12) + " bytes left");
        h.contentBegin = at + 12;
        h.contentEnd = h.contentBegin + std::size_t(content);
        h.childrenEnd = h.contentEnd + std::size_t(children);
        return h;
    };

    const Header main = readHeader(8, size, "the file");
    if (main.id != "MAIN")
        fail(main.label, "expected the MAIN chunk at byte 8, found " + quote(main.id));
    // Bytes after MAIN are not part of any chunk; like other readers we ignore them.
    for (std::size_t at = main.contentEnd; at < main.childrenEnd;) {
        const Header h = readHeader(at, main.childrenEnd, "MAIN");
        parseChunk(h.id, h.label, h.contentBegin, h.contentEnd);
        at = h.childrenEnd;
    }

    if (pendingSize_) fail(pendingSizeLabel_, "model size is not followed by an XYZI chunk");
    if (out_.models.empty()) fail("MAIN", "no models: the file has no SIZE/XYZI chunk pair");
    if (!out_.hasPaletteChunk) out_.palette = magicaVoxelDefaultPalette();
    if (!nodes_.empty()) flattenSceneGraph();
    return std::move(out_);
}

void Parser::parseChunk(const std::string& id, const std::string& label, std::size_t begin,
                        std::size_t end) {
    Cursor c(bytes_, begin, end, out_.source, label, "chunk");
    if (id == "SIZE") {
        parseSize(c);
    } else if (id == "XYZI") {
        parseXyzi(c);
    } else if (id == "RGBA") {
        parseRgba(c);
    } else if (id == "nTRN") {
        parseTransform(c);
    } else if (id == "nGRP") {
        parseGroup(c);
    } else if (id == "nSHP") {
        parseShape(c);
    } else if (id == "LAYR") {
        parseLayer(c);
    } else if (id == "META") {
        parseMeta(c);
    } else if (id == "PACK") {
        // The model count is implied by the SIZE/XYZI pairs; PACK only announces it.
        c.i32("model count");
    }
    // Everything else (IMAP, MATL, MATT, rOBJ, rCAM, NOTE, rLIT, POST, unknown ids) carries
    // nothing the renderer uses; it was already counted and is skipped by its size fields.
}

void Parser::parseSize(Cursor& c) {
    if (pendingSize_)
        fail(pendingSizeLabel_, "model size is followed by another SIZE chunk, not by XYZI");
    glm::ivec3 s;
    s.x = c.i32("size x");
    s.y = c.i32("size y");
    s.z = c.i32("size z");
    for (int a = 0; a < 3; ++a)
        if (s[a] < 1 || s[a] > Limits::kMaxModelDim)
            c.fail("model size " + std::to_string(s.x) + "x" + std::to_string(s.y) + "x" +
                   std::to_string(s.z) + " outside 1.." + std::to_string(Limits::kMaxModelDim) +
                   " per axis");
    pendingSize_ = s;
    pendingSizeLabel_ = c.field();
}

void Parser::parseXyzi(Cursor& c) {
    if (!pendingSize_) c.fail("XYZI chunk before any SIZE chunk: the model has no size");
    const glm::ivec3 s = *pendingSize_;
    pendingSize_.reset();
    const std::size_t n = c.count("voxel count", 4);
    const std::size_t cells = std::size_t(s.x) * std::size_t(s.y) * std::size_t(s.z);
    if (cells > limits_.maxVoxelCells - voxelCells_)
        c.fail("the models need more than the reader's limit of " +
               std::to_string(limits_.maxVoxelCells) + " voxel cells");
    voxelCells_ += cells;
    VoxelGrid grid(s, out_.source);
    for (std::size_t i = 0; i < n; ++i) {
        const int x = c.u8(), y = c.u8(), z = c.u8();
        const std::uint8_t colour = c.u8();
        if (x >= s.x || y >= s.y || z >= s.z)
            c.fail("voxel " + std::to_string(i) + " at (" + std::to_string(x) + ", " +
                   std::to_string(y) + ", " + std::to_string(z) + ") lies outside the model size " +
                   std::to_string(s.x) + "x" + std::to_string(s.y) + "x" + std::to_string(s.z));
        // Colour 0 is MagicaVoxel's "empty"; writing it keeps "last voxel wins" uniform.
        grid.set({x, y, z}, colour);
    }
    out_.models.push_back(std::move(grid));
}

void Parser::parseRgba(Cursor& c) {
    c.need(1024, "the palette (256 RGBA entries)");
    Palette p;
    // Entry i is palette index i + 1; the 256th entry has no index and is dropped, and
    // index 0 stays transparent black like the default palette's.
    for (std::size_t i = 0; i < 255; ++i) {
        const unsigned r = c.u8(), g = c.u8(), b = c.u8(), a = c.u8();
        p.colors[i + 1] = packRgba(r, g, b, a);
    }
    out_.palette = p;
    out_.hasPaletteChunk = true;
}

std::int32_t Parser::readNodeId(Cursor& c, const char* kind) {
    const std::size_t at = c.offset();
    const std::int32_t id = c.i32("node id");
    if (id < 0) c.fail("negative node id " + std::to_string(id) + " at byte " + std::to_string(at));
    c.setField(std::string(kind) + " node " + std::to_string(id));
    return id;
}

void Parser::addNode(std::int32_t id, SceneNode node, const Cursor& c) {
    node.label = c.field();
    if (!nodeIndex_.try_emplace(id, nodes_.size()).second)
        c.fail("node id " + std::to_string(id) + " is defined twice");
    nodes_.push_back(std::move(node));
}

void Parser::parseTransform(Cursor& c) {
    SceneNode node;
    node.kind = SceneNode::Kind::Transform;
    const std::int32_t id = readNodeId(c, "nTRN");
    const Dict attributes = c.dict("node attributes");
    if (const auto* h = findKey(attributes, "_hidden")) node.hidden = *h == "1";
    if (const auto* n = findKey(attributes, "_name")) node.name = *n;
    node.child = c.i32("child node id");
    c.i32("reserved id"); // "must be -1"; nothing depends on it, so it is not enforced
    node.layer = c.i32("layer id");
    // Every frame dict is at least its 4-byte pair count.
    const std::size_t frames = c.count("frame count", 4);
    for (std::size_t f = 0; f < frames; ++f) {
        const Dict frame = c.dict("frame " + std::to_string(f) + " attributes");
        // Animated transforms: the static instance uses keyframe 0 (see VoxInstance).
        if (f != 0) continue;
        if (const auto* r = findKey(frame, "_r")) {
            const auto bits = parseInt(*r);
            if (!bits || *bits < 0 || *bits > 255)
                c.fail("_r " + quote(*r) + " is not a rotation byte (0..255)");
            const auto m = decodeVoxRotation(unsigned(*bits));
            if (!m)
                c.fail("_r " + std::to_string(*bits) + " is not a valid rotation (row 0 column " +
                       std::to_string(*bits & 3) + ", row 1 column " +
                       std::to_string((*bits >> 2) & 3) + ")");
            node.rotation = *m;
        }
        if (const auto* t = findKey(frame, "_t")) {
            const auto v = parseInts(*t, 3);
            if (!v) c.fail("_t " + quote(*t) + " is not three 32-bit integers");
            node.translation = {(*v)[0], (*v)[1], (*v)[2]};
        }
        if (const auto* fi = findKey(frame, "_f")) {
            const auto v = parseInt(*fi);
            if (!v) c.fail("_f " + quote(*fi) + " is not a 32-bit integer");
            node.frame = *v;
        }
    }
    addNode(id, std::move(node), c);
}

void Parser::parseGroup(Cursor& c) {
    SceneNode node;
    node.kind = SceneNode::Kind::Group;
    const std::int32_t id = readNodeId(c, "nGRP");
    const Dict attributes = c.dict("node attributes");
    if (const auto* h = findKey(attributes, "_hidden")) node.hidden = *h == "1";
    const std::size_t n = c.count("child count", 4);
    node.children.reserve(n);
    for (std::size_t i = 0; i < n; ++i) node.children.push_back(c.i32("child node id"));
    addNode(id, std::move(node), c);
}

void Parser::parseShape(Cursor& c) {
    SceneNode node;
    node.kind = SceneNode::Kind::Shape;
    const std::int32_t id = readNodeId(c, "nSHP");
    const Dict attributes = c.dict("node attributes");
    if (const auto* h = findKey(attributes, "_hidden")) node.hidden = *h == "1";
    // Each model entry is a 4-byte id and a dict of at least 4 bytes.
    const std::size_t n = c.count("model count", 8);
    for (std::size_t i = 0; i < n; ++i) {
        const std::int32_t model = c.i32("model id");
        c.dict("model " + std::to_string(i) + " attributes");
        // Animated shapes list one model per keyframe; the static instance uses the first.
        if (i == 0) node.model = model;
    }
    addNode(id, std::move(node), c);
}

void Parser::parseLayer(Cursor& c) {
    const std::int32_t id = c.i32("layer id");
    c.setField(c.field() + " (layer " + std::to_string(id) + ")");
    const Dict attributes = c.dict("layer attributes");
    const auto* h = findKey(attributes, "_hidden");
    layerHidden_[id] = h && *h == "1";
    // The trailing reserved int is not read: nothing depends on it.
}

void Parser::parseMeta(Cursor& c) {
    const Dict attributes = c.dict("attributes");
    if (const auto* range = findKey(attributes, "_anim_range")) {
        const auto v = parseInts(*range, 2);
        if (!v) c.fail("_anim_range " + quote(*range) + " is not two 32-bit integers");
        out_.animRange = std::pair{(*v)[0], (*v)[1]};
    }
}

void Parser::flattenSceneGraph() {
    const auto root = nodeIndex_.find(0);
    if (root == nodeIndex_.end())
        fail("scene graph", "no root node 0 among its " + std::to_string(nodes_.size()) + " nodes");

    // Iterative depth-first walk over every path from the root (a node reached through
    // several parents is visited once per path: that is instancing). onPath catches cycles,
    // the visit budget bounds DAGs whose path count explodes.
    struct Entry {
        std::size_t node;
        PathState state;
        std::size_t nextChild = 0;
    };
    std::vector<Entry> path;
    std::vector<char> onPath(nodes_.size(), 0);
    std::size_t visits = 0;

    auto enter = [&](std::int32_t childId, const PathState& parent, const std::string& from) {
        const auto it = nodeIndex_.find(childId);
        if (it == nodeIndex_.end())
            fail(from, "child node " + std::to_string(childId) + " does not exist");
        const std::size_t index = it->second;
        if (onPath[index])
            fail(from, "child node " + std::to_string(childId) +
                           " is also its ancestor (cycle in the scene graph)");
        if (++visits > limits_.maxSceneNodeVisits)
            fail("scene graph", "expands to more than " +
                                    std::to_string(limits_.maxSceneNodeVisits) +
                                    " node visits (too much instancing)");
        const SceneNode& node = nodes_[index];
        PathState s = parent;
        s.hidden = s.hidden || node.hidden;
        if (node.kind == SceneNode::Kind::Transform) {
            // parent * node: rotations multiply, the node's translation is rotated into the
            // parent's frame before it is added.
            s.rotation = parent.rotation * node.rotation;
            for (int row = 0; row < 3; ++row) {
                std::int64_t v = parent.translation[row];
                for (int col = 0; col < 3; ++col)
                    v += std::int64_t(parent.rotation[col][row]) * node.translation[col];
                // |v| <= 2^31 + 3 * 2^31 here, far inside int64; the check keeps it int32.
                if (v < std::numeric_limits<std::int32_t>::min() ||
                    v > std::numeric_limits<std::int32_t>::max())
                    fail(node.label, "translation overflows 32-bit integers when composed "
                                     "with its parents");
                s.translation[row] = v;
            }
            if (!node.name.empty()) s.name = &node.name;
            if (node.frame) s.frame = *node.frame;
            if (const auto layer = layerHidden_.find(node.layer);
                layer != layerHidden_.end() && layer->second)
                s.hidden = true;
        }
        onPath[index] = 1;
        path.push_back({index, s});
    };

    enter(0, PathState{}, "scene graph");
    while (!path.empty()) {
        Entry& top = path.back();
        const SceneNode& node = nodes_[top.node];
        std::optional<std::int32_t> next;
        switch (node.kind) {
        case SceneNode::Kind::Transform:
            if (top.nextChild++ == 0) next = node.child;
            break;
        case SceneNode::Kind::Group:
            if (top.nextChild < node.children.size()) next = node.children[top.nextChild++];
            break;
        case SceneNode::Kind::Shape:
            if (node.model) {
                if (*node.model < 0 || std::size_t(*node.model) >= out_.models.size())
                    fail(node.label, "model id " + std::to_string(*node.model) +
                                         " but the file has " + std::to_string(out_.models.size()) +
                                         " models");
                if (out_.instances.size() >= limits_.maxInstances)
                    fail("scene graph", "expands to more than " +
                                            std::to_string(limits_.maxInstances) + " instances");
                VoxInstance inst;
                inst.model = *node.model;
                inst.rotation = top.state.rotation;
                inst.translation =
                    glm::ivec3(int(top.state.translation[0]), int(top.state.translation[1]),
                               int(top.state.translation[2]));
                inst.hidden = top.state.hidden;
                if (top.state.name) inst.name = *top.state.name;
                inst.frameIndex = top.state.frame;
                out_.instances.push_back(std::move(inst));
            }
            break;
        }
        if (next) {
            // Copy: enter() may reallocate `path` and invalidate `top`.
            const PathState state = top.state;
            enter(*next, state, node.label);
        } else {
            onPath[top.node] = 0;
            path.pop_back();
        }
    }
}

} // namespace

VoxFile parseVox(std::span<const std::uint8_t> bytes, const std::string& source,
                 const VoxReadLimits& limits) {
    return Parser(bytes, source, limits).run();
}

VoxFile readVoxFile(const std::filesystem::path& file, const VoxReadLimits& limits) {
    const std::string name = file.string();
    std::error_code ec;
    const auto status = std::filesystem::status(file, ec);
    if (ec || !std::filesystem::exists(status))
        throw InputError(name, "", "cannot open: " + (ec ? ec.message() : "no such file"));
    if (!std::filesystem::is_regular_file(status))
        throw InputError(name, "", "cannot open: not a regular file");
    const std::uintmax_t size = std::filesystem::file_size(file, ec);
    if (ec) throw InputError(name, "", "cannot read its size: " + ec.message());
    if (size > limits.maxFileBytes)
        throw InputError(name, "",
                         "file has " + std::to_string(size) +
                             " bytes, more than the reader's limit of " +
                             std::to_string(limits.maxFileBytes));
    std::ifstream in(file, std::ios::binary);
    if (!in) throw InputError(name, "", "cannot open for reading");
    std::vector<std::uint8_t> bytes(static_cast<std::size_t>(size));
    in.read(reinterpret_cast<char*>(bytes.data()), static_cast<std::streamsize>(size));
    if (in.gcount() != static_cast<std::streamsize>(size))
        throw InputError(name, "",
                         "read " + std::to_string(in.gcount()) + " of " + std::to_string(size) +
                             " bytes");
    return parseVox(bytes, name, limits);
}

} // namespace voxtier
