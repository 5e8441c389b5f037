// The GIF89a encoder of image_files/detail/gif_encoder.hpp. It follows the GIF89a specification
// (CompuServe, 1990): the block layout of its sections 17-27, the variable-length LZW of its
// appendix F (codes grow from the minimum code size + 1 to 12 bits; a clear code restarts the
// table when it is full). The palette of a frame with too many colours is chosen by median cut
// (Heckbert, "Color Image Quantization for Frame Buffer Display", SIGGRAPH 1982), splitting the
// box with the largest squared error at its weighted median.
#include "image_files/detail/gif_encoder.hpp"

#include <algorithm>
#include <array>
#include <cassert>
#include <limits>
#include <unordered_map>

namespace voxtier::detail {

namespace {

constexpr std::uint32_t kRgb = 0x00FFFFFFu;
constexpr int kMaxCodeBits = 12;
constexpr unsigned kTableCodes = 1u << kMaxCodeBits; // 4096

void put16(std::vector<std::uint8_t>& out, unsigned v) {
    out.push_back(std::uint8_t(v & 0xFF));
    out.push_back(std::uint8_t((v >> 8) & 0xFF));
}

unsigned red(std::uint32_t c) {
    return c & 0xFF;
}
unsigned green(std::uint32_t c) {
    return (c >> 8) & 0xFF;
}
unsigned blue(std::uint32_t c) {
    return (c >> 16) & 0xFF;
}

/// The LZW code stream of `indices` (each below 2^minCodeSize) as GIF data sub-blocks, after the
/// minimum code size byte, ending with the block terminator.
void writeLzw(const std::vector<std::uint8_t>& indices, int minCodeSize,
              std::vector<std::uint8_t>& out) {
    out.push_back(std::uint8_t(minCodeSize));
    const unsigned clear = 1u << minCodeSize, endOfInformation = clear + 1;
    std::vector<std::uint8_t> data;
    std::uint32_t bits = 0;
    int bitCount = 0;
    int codeSize = minCodeSize + 1;
    const auto emit = [&](unsigned code) {
        bits |= std::uint32_t(code) << bitCount;
        bitCount += codeSize;
        while (bitCount >= 8) {
            data.push_back(std::uint8_t(bits & 0xFF));
            bits >>= 8;
            bitCount -= 8;
        }
    };
    // The string table: (prefix code, next index) -> code, open addressing over twice the codes.
    constexpr std::size_t kSlots = 2 * kTableCodes;
    std::vector<std::uint32_t> keys(kSlots);
    std::vector<std::int16_t> codes(kSlots);
    unsigned nextCode = 0;
    const auto restart = [&] {
        std::fill(codes.begin(), codes.end(), std::int16_t(-1));
        codeSize = minCodeSize + 1;
        nextCode = endOfInformation + 1;
    };
    const auto slotOf = [&](std::uint32_t key) {
        std::size_t s = (key * 2654435761u) >> (32 - 13); // 13 bits: kSlots
        while (codes[s] >= 0 && keys[s] != key) s = (s + 1) & (kSlots - 1);
        return s;
    };
    // A decoder adds a table entry for every code it reads after the first and widens its codes
    // once the next entry would not fit: counting a code here the same way keeps both widths equal.
    const auto counted = [&] {
        ++nextCode;
        if (nextCode > (1u << codeSize) && codeSize < kMaxCodeBits) ++codeSize;
    };
    restart();
    emit(clear);
    if (!indices.empty()) {
        unsigned prefix = indices[0];
        for (std::size_t i = 1; i < indices.size(); ++i) {
            const std::uint32_t key = (std::uint32_t(prefix) << 8) | indices[i];
            const std::size_t s = slotOf(key);
            if (codes[s] >= 0) {
                prefix = unsigned(codes[s]);
                continue;
            }
            emit(prefix);
            keys[s] = key;
            codes[s] = std::int16_t(nextCode);
            counted();
            if (nextCode == kTableCodes) { // full: start a new table
                emit(clear);
                restart();
            }
            prefix = indices[i];
        }
        emit(prefix);
        counted();
    }
    emit(endOfInformation);
    if (bitCount > 0) data.push_back(std::uint8_t(bits & 0xFF));
    for (std::size_t at = 0; at < data.size(); at += 255) {
        const std::size_t n = std::min<std::size_t>(255, data.size() - at);
        out.push_back(std::uint8_t(n));
        out.insert(out.end(), data.begin() + std::ptrdiff_t(at),
                   data.begin() + std::ptrdiff_t(at + n));
    }
    out.push_back(0); // block terminator
}

struct ColourCount {
    std::uint32_t rgb = 0;
    std::uint64_t count = 0;
};

/// Up to `k` colours for `colours` (distinct, with their pixel counts) by median cut: each box's
/// palette colour is its pixels' mean.
std::vector<std::uint32_t> medianCut(std::vector<ColourCount> colours, std::size_t k) {
    struct Box {
        std::size_t begin, end;
        double error = 0.0; ///< squared distance of its pixels to their mean
        int axis = 0;       ///< the channel of the largest spread
        std::array<double, 3> mean{};
    };
    const auto measure = [&](Box& b) {
        std::array<double, 3> sum{}, sumSq{};
        double n = 0.0;
        for (std::size_t i = b.begin; i < b.end; ++i) {
            const double w = double(colours[i].count);
            const std::array<double, 3> c = {double(red(colours[i].rgb)),
                                             double(green(colours[i].rgb)),
                                             double(blue(colours[i].rgb))};
            for (int a = 0; a < 3; ++a) {
                sum[std::size_t(a)] += w * c[std::size_t(a)];
                sumSq[std::size_t(a)] += w * c[std::size_t(a)] * c[std::size_t(a)];
            }
            n += w;
        }
        b.error = 0.0;
        double widest = -1.0;
        for (int a = 0; a < 3; ++a) {
            b.mean[std::size_t(a)] = sum[std::size_t(a)] / n;
            const double e = sumSq[std::size_t(a)] - sum[std::size_t(a)] * b.mean[std::size_t(a)];
            b.error += e;
            if (e > widest) widest = e, b.axis = a;
        }
        if (b.end - b.begin < 2) b.error = 0.0; // one colour: nothing to split
    };
    std::vector<Box> boxes(1, Box{0, colours.size()});
    measure(boxes[0]);
    while (boxes.size() < k) {
        const auto worst =
            std::max_element(boxes.begin(), boxes.end(),
                             [](const Box& a, const Box& b) { return a.error < b.error; });
        if (worst->error <= 0.0) break;
        Box b = *worst;
        const int shift = 8 * b.axis;
        std::sort(colours.begin() + std::ptrdiff_t(b.begin),
                  colours.begin() + std::ptrdiff_t(b.end),
                  [shift](const ColourCount& x, const ColourCount& y) {
                      return ((x.rgb >> shift) & 0xFF) < ((y.rgb >> shift) & 0xFF);
                  });
        std::uint64_t total = 0, below = 0;
        for (std::size_t i = b.begin; i < b.end; ++i) total += colours[i].count;
        std::size_t cut = b.begin + 1;
        for (std::size_t i = b.begin; i + 1 < b.end; ++i) {
            below += colours[i].count;
            cut = i + 1;
            if (2 * below >= total) break;
        }
        Box lo{b.begin, cut}, hi{cut, b.end};
        measure(lo);
        measure(hi);
        *worst = lo;
        boxes.push_back(hi);
    }
    std::vector<std::uint32_t> palette;
    for (const Box& b : boxes) {
        const auto round = [](double v) { return unsigned(std::clamp(v + 0.5, 0.0, 255.0)); };
        palette.push_back(round(b.mean[0]) | round(b.mean[1]) << 8 | round(b.mean[2]) << 16);
    }
    return palette;
}

/// The index of the palette colour nearest `c` (squared RGB distance; the lower index on a tie).
std::uint8_t nearest(const std::vector<std::uint32_t>& palette, std::uint32_t c) {
    std::size_t best = 0;
    int bestDistance = std::numeric_limits<int>::max();
    for (std::size_t i = 0; i < palette.size(); ++i) {
        const int dr = int(red(c)) - int(red(palette[i])),
                  dg = int(green(c)) - int(green(palette[i])),
                  db = int(blue(c)) - int(blue(palette[i]));
        const int d = dr * dr + dg * dg + db * db;
        if (d < bestDistance) bestDistance = d, best = i;
    }
    return std::uint8_t(best);
}

/// Distinct colours of `pixels` (RGB) with their counts.
std::vector<ColourCount> histogram(const std::vector<std::uint32_t>& pixels) {
    std::unordered_map<std::uint32_t, std::uint64_t> counts;
    std::uint32_t last = ~0u;
    std::uint64_t* lastCount = nullptr;
    for (const std::uint32_t c : pixels) {
        if (c != last) lastCount = &counts[c], last = c; // runs are common: skip the lookup
        ++*lastCount;
    }
    std::vector<ColourCount> out;
    out.reserve(counts.size());
    for (const auto& [rgb, n] : counts) out.push_back({rgb, n});
    // Sorted, so that the palette (and the file) does not depend on the hash table's order.
    std::sort(out.begin(), out.end(),
              [](const ColourCount& a, const ColourCount& b) { return a.rgb < b.rgb; });
    return out;
}

} // namespace

GifEncoder::GifEncoder(int width, int height, bool animation)
    : width_(width), height_(height), animation_(animation),
      canvas_(std::size_t(width) * std::size_t(height)) {
    assert(width >= 1 && width <= 65535 && height >= 1 && height <= 65535);
}

GifFrameFidelity GifEncoder::add(const Image& img, int delayCs) {
    assert(img.width == width_ && img.height == height_);
    const bool first = frames_++ == 0;
    const auto rgb = [&](int x, int y) { return img.color[img.index(x, y)] & kRgb; };
    const auto shown = [&](int x, int y) -> std::uint32_t& {
        return canvas_[std::size_t(y) * std::size_t(width_) + std::size_t(x)];
    };
    // The rectangle to store: everything for the first frame, else around every pixel whose
    // colour differs from what a decoder shows now.
    int x0 = 0, y0 = 0, x1 = width_, y1 = height_;
    if (!first) {
        x0 = width_, y0 = height_, x1 = 0, y1 = 0;
        for (int y = 0; y < height_; ++y)
            for (int x = 0; x < width_; ++x)
                if (rgb(x, y) != shown(x, y)) {
                    x0 = std::min(x0, x), x1 = std::max(x1, x + 1);
                    y0 = std::min(y0, y), y1 = std::max(y1, y + 1);
                }
        if (x1 <= x0) x0 = 0, y0 = 0, x1 = 1, y1 = 1; // nothing changed: one transparent pixel
    }
    // Its pixels that need a colour: all of the first frame, else those that differ.
    std::vector<std::uint32_t> changed, all;
    for (int y = y0; y < y1; ++y)
        for (int x = x0; x < x1; ++x) {
            all.push_back(rgb(x, y));
            if (first || rgb(x, y) != shown(x, y)) changed.push_back(rgb(x, y));
        }
    // Transparency for the pixels already right costs one palette entry; where the changed
    // pixels need all 256, the rectangle may still fit opaque.
    bool transparent = !first;
    std::vector<ColourCount> colours = histogram(changed);
    if (transparent && colours.size() > 255) {
        std::vector<ColourCount> opaque = histogram(all);
        if (opaque.size() <= 256) transparent = false, colours = std::move(opaque);
    }
    const std::size_t room = transparent ? 255 : 256;
    GifFrameFidelity fidelity;
    std::vector<std::uint32_t> palette;
    std::unordered_map<std::uint32_t, std::uint8_t> indexOf;
    if (colours.size() <= room) {
        for (const ColourCount& c : colours) {
            indexOf[c.rgb] = std::uint8_t(palette.size());
            palette.push_back(c.rgb);
        }
    } else {
        palette = medianCut(colours, room);
        for (const ColourCount& c : colours) indexOf[c.rgb] = nearest(palette, c.rgb);
        fidelity.exact = false;
        std::vector<std::uint32_t> frame(img.pixelCount());
        for (std::size_t i = 0; i < frame.size(); ++i) frame[i] = img.color[i] & kRgb;
        fidelity.colours = histogram(frame).size();
    }
    const std::size_t transparentIndex = palette.size();
    std::size_t entries = palette.size() + (transparent ? 1 : 0);
    int tableBits = 1;
    while ((std::size_t(1) << tableBits) < entries) ++tableBits;
    // The frame's indices, and what a decoder shows after it.
    std::vector<std::uint8_t> indices;
    indices.reserve(all.size());
    std::uint32_t last = ~0u;
    std::uint8_t lastIndex = 0;
    for (int y = y0; y < y1; ++y)
        for (int x = x0; x < x1; ++x) {
            const std::uint32_t c = rgb(x, y);
            if (transparent && c == shown(x, y)) {
                indices.push_back(std::uint8_t(transparentIndex));
                continue;
            }
            if (c != last) lastIndex = indexOf.at(c), last = c; // runs are common
            indices.push_back(lastIndex);
            shown(x, y) = palette[lastIndex];
        }
    // Graphic Control Extension: "do not dispose" (the next frame draws over this one), the
    // delay, the transparent index.
    if (animation_ || transparent) {
        body_.insert(body_.end(), {0x21, 0xF9, 0x04});
        body_.push_back(std::uint8_t((1 << 2) | (transparent ? 1 : 0)));
        put16(body_, unsigned(std::clamp(delayCs, 0, 65535)));
        body_.push_back(std::uint8_t(transparent ? transparentIndex : 0));
        body_.push_back(0);
    }
    // Image Descriptor with its local colour table, then the image data.
    body_.push_back(0x2C);
    put16(body_, unsigned(x0));
    put16(body_, unsigned(y0));
    put16(body_, unsigned(x1 - x0));
    put16(body_, unsigned(y1 - y0));
    body_.push_back(std::uint8_t(0x80 | (tableBits - 1)));
    for (std::size_t i = 0; i < (std::size_t(1) << tableBits); ++i) {
        const std::uint32_t c = i < palette.size() ? palette[i] : 0;
        body_.insert(body_.end(),
                     {std::uint8_t(red(c)), std::uint8_t(green(c)), std::uint8_t(blue(c))});
    }
    writeLzw(indices, std::max(2, tableBits), body_);
    return fidelity;
}

std::vector<std::uint8_t> GifEncoder::finish() {
    std::vector<std::uint8_t> out = {'G', 'I', 'F', '8', '9', 'a'};
    // Logical Screen Descriptor: no global colour table (every frame has its own).
    put16(out, unsigned(width_));
    put16(out, unsigned(height_));
    out.insert(out.end(), {0x70, 0x00, 0x00}); // 8-bit colour resolution, background 0, no aspect
    if (animation_ && frames_ > 1) {
        // The NETSCAPE2.0 application extension: loop forever.
        out.insert(out.end(), {0x21, 0xFF, 0x0B, 'N', 'E', 'T', 'S', 'C', 'A', 'P', 'E', '2', '.',
                               '0', 0x03, 0x01, 0x00, 0x00, 0x00});
    }
    out.insert(out.end(), body_.begin(), body_.end());
    out.push_back(0x3B); // trailer
    return out;
}

} // namespace voxtier::detail
