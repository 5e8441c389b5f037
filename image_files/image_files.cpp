#include "image_files/image_files.hpp"

#include "core/error.hpp"
#include "core/file_write.hpp"
#include "core/sprite_kernel.h"
#include "image_files/detail/gif_encoder.hpp"
#include "image_files/detail/image_library.hpp"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

namespace voxtier {

std::string lowerExtension(const std::filesystem::path& file) {
    std::string ext = file.extension().string();
    for (char& c : ext) c = char(std::tolower(static_cast<unsigned char>(c)));
    return ext;
}

namespace {

/// Netpbm PAM (P7): a text header, then the RGBA bytes of each row from the top.
void writePam(const std::filesystem::path& file, const Image& img) {
    const std::string header = "P7\nWIDTH " + std::to_string(img.width) + "\nHEIGHT " +
                               std::to_string(img.height) +
                               "\nDEPTH 4\nMAXVAL 255\nTUPLTYPE RGB_ALPHA\nENDHDR\n";
    std::vector<std::uint8_t> bytes(header.begin(), header.end());
    bytes.reserve(header.size() + img.pixelCount() * 4);
    for (std::size_t i = 0; i < img.pixelCount(); ++i)
        for (int c = 0; c < 4; ++c) bytes.push_back(std::uint8_t(channel(img.color[i], c)));
    writeFileWhole(file, bytes);
}

/// A still GIF (gif_encoder.hpp): exact where the image has at most 256 colours.
void writeGif(const std::filesystem::path& file, const Image& img) {
    detail::GifEncoder gif(img.width, img.height, false);
    gif.add(img, 0);
    writeFileWhole(file, gif.finish());
}

} // namespace

bool imageLibraryAvailable() {
    return detail::imageLibraryLoaded();
}

bool canWriteImageFormat(const std::filesystem::path& file) {
    return imageFormatRefusal(file).empty();
}

std::string imageFormatRefusal(const std::filesystem::path& file) {
    const std::string ext = lowerExtension(file);
    if (ext == ".pam" || ext == ".gif" || imageLibraryAvailable()) return "";
    return "cannot write " + (ext.empty() ? std::string("a file without an extension") : ext) +
           ": " + detail::imageLibraryFailure() + "; write .pam or .gif";
}

namespace {

void write(const std::filesystem::path& file, const Image& img, double zNear, bool colorOnly) {
    if (lowerExtension(file) == ".pam") return writePam(file, img);
    if (lowerExtension(file) == ".gif") return writeGif(file, img);
    const std::string refusal = imageFormatRefusal(file);
    if (!refusal.empty()) throw InputError(file.string(), "", refusal);
    detail::writeWithImageLibrary(file, img, zNear, colorOnly);
}

} // namespace

void writeImage(const std::filesystem::path& file, const Image& img, double zNear) {
    write(file, img, zNear, false);
}

Rgba8 idColor(std::uint32_t id) {
    // Multiplying by a number prime to 191^3 permutes the residues mod 191^3 (so distinct ids
    // below it keep distinct colours) and scatters neighbours; the base-191 digits of the result
    // are the channels.
    constexpr std::uint64_t kLevels = 191, kColors = kLevels * kLevels * kLevels;
    constexpr std::uint64_t kScatter = 2654435761u % kColors;
    static_assert(kScatter % kLevels != 0, "the multiplier must be prime to 191^3");
    const std::uint64_t h = (std::uint64_t(id) % kColors) * kScatter % kColors;
    return packRgba(unsigned(64 + h % kLevels), unsigned(64 + h / kLevels % kLevels),
                    unsigned(64 + h / (kLevels * kLevels)));
}

void writeIdImage(const std::filesystem::path& file, const Image& img) {
    Image vis = img;
    for (std::size_t i = 0; i < img.pixelCount(); ++i)
        vis.color[i] = img.id[i] == kernel::VT_NO_ENTITY ? packRgba(0, 0, 0) : idColor(img.id[i]);
    // The colour-coded ids alone, also in an EXR (no Z or id channels).
    write(file, vis, 0.0, true);
}

std::string gifFidelityNote(const std::filesystem::path& file, const GifFidelity& f) {
    if (f.approximated == 0) return "";
    const std::string frames = f.frames == 1 ? "the image has"
                                             : std::to_string(f.approximated) + " of " +
                                                   std::to_string(f.frames) + " frames have";
    return file.string() + ": " + frames + " more colours than GIF's 256 a frame (up to " +
           std::to_string(f.mostColours) +
           "), so those are drawn in the nearest of 256 colours (no dithering); for exact "
           "pixels write .png (a sequence: numbered PNGs) or .pam";
}

namespace {

/// The GIF delay of frame `k` (1/100 s): frame k starts at round(100 k / fps) centiseconds, so
/// that the delays sum to the path's duration and the average frame rate is fps (30 fps:
/// 3, 3, 4, 3, 3, 4 ...) instead of 100 / round(100 / fps) (33.3 fps at 30).
int gifDelay(double fps, std::size_t k) {
    const auto start = [fps](std::size_t i) { return std::llround(100.0 * double(i) / fps); };
    return int(std::clamp<long long>(start(k + 1) - start(k), 1, 65535));
}

} // namespace

struct AnimationWriter::Impl {
    std::filesystem::path file;
    double fps = 30.0;
    /// The frames are encoded into memory and reach the disk whole at close(): a run killed or
    /// failing part-way leaves no shorter GIF that looks complete.
    std::optional<detail::GifEncoder> gif;
    int width = 0, height = 0;
    GifFidelity fidelity;
};

AnimationWriter::AnimationWriter(std::filesystem::path file, double fps)
    : impl_(std::make_unique<Impl>()) {
    if (lowerExtension(file) != ".gif")
        throw InputError(file.string(), "", "cannot write an animation in this format (use .gif)");
    impl_->file = std::move(file);
    impl_->fps = fps;
}

AnimationWriter::~AnimationWriter() = default;

void AnimationWriter::add(const Image& img) {
    Impl& m = *impl_;
    if (!m.gif) {
        if (img.width > 65535 || img.height > 65535)
            throw InputError(m.file.string(), "", "a GIF holds at most 65535 pixels a side");
        m.gif.emplace(img.width, img.height, true);
        m.width = img.width, m.height = img.height;
    } else if (img.width != m.width || img.height != m.height) {
        throw InputError(m.file.string(), "", "animation frames must all be the same size");
    }
    const detail::GifFrameFidelity f = m.gif->add(img, gifDelay(m.fps, m.fidelity.frames));
    ++m.fidelity.frames;
    if (!f.exact) {
        ++m.fidelity.approximated;
        m.fidelity.mostColours = std::max(m.fidelity.mostColours, f.colours);
    }
}

void AnimationWriter::close() {
    Impl& m = *impl_;
    if (!m.gif) return;
    writeFileWhole(m.file, m.gif->finish());
    m.gif.reset();
}

const GifFidelity& AnimationWriter::fidelity() const {
    return impl_->fidelity;
}

} // namespace voxtier
