// The formats that need an image library (.png, .exr, .tif, .jpg), where VOXTIER_IMAGE_FILES=ON:
// the pixels laid out here, encoded and decoded by OpenImageIO in libvoxtier_openimageio.so
// (image_files/openimageio_module.cpp), which this file loads on the first call that needs it
// (image_files/detail/image_library_module.hpp says why it is not linked).
#include "core/error.hpp"
#include "core/file_write.hpp"
#include "core/sprite_kernel.h"
#include "image_files/detail/image_library.hpp"
#include "image_files/detail/image_library_module.hpp"
#include "image_files/image_files.hpp"

#include <algorithm>
#include <cmath>
#include <dlfcn.h>
#include <limits>
#include <system_error>

namespace voxtier {

namespace {

/// The module, or why it could not be loaded.
struct LoadedModule {
    const detail::ImageLibraryModule* api = nullptr;
    std::string failure;
};

/// Opens `path` and checks its entry; "" and `api` set on success.
std::string openModule(const std::string& path, const detail::ImageLibraryModule*& api) {
    void* handle = dlopen(path.c_str(), RTLD_NOW | RTLD_LOCAL);
    if (!handle) {
        const char* why = dlerror();
        return why ? why : path + ": cannot be loaded";
    }
    using Entry = const detail::ImageLibraryModule* (*)();
    const auto entry = reinterpret_cast<Entry>(dlsym(handle, detail::kImageLibraryEntry));
    if (!entry) return path + ": no " + detail::kImageLibraryEntry;
    const detail::ImageLibraryModule* module = entry();
    if (!module || module->abi != detail::kImageLibraryAbi)
        return path + " is from another build of voxtier (interface " +
               std::to_string(module ? module->abi : 0) + ", this one " +
               std::to_string(detail::kImageLibraryAbi) + ")";
    api = module; // the handle stays open for the process's life
    return "";
}

/// Where the module is looked for, in order:
/// 1. by its bare name: the dynamic loader's search (LD_LIBRARY_PATH, and the run path that
///    voxtier::image_files gives a program built against an installed voxtier, CMakeLists.txt);
/// 2. <the program's folder>/../<libdir>/voxtier/: the installed CLI;
/// 3. where the build tree made it, for a program inside that build tree (its CLI, tests and
///    examples): an installed program never reaches into the tree it was built in.
/// A file that exists but fails to load (a missing dependency of OpenImageIO's, a stale module)
/// is reported by the loader's own message, which names what failed.
LoadedModule loadModule() {
    LoadedModule loaded;
    if (openModule(detail::kImageLibraryFile, loaded.api).empty()) return loaded;
    std::vector<std::string> places;
    std::error_code ec;
    const std::filesystem::path self = std::filesystem::read_symlink("/proc/self/exe", ec);
    if (!ec) {
        places.push_back((self.parent_path().parent_path() / VOXTIER_IMAGE_MODULE_LIBDIR /
                          "voxtier" / detail::kImageLibraryFile)
                             .string());
        const std::filesystem::path tree = VOXTIER_IMAGE_MODULE_BUILD_TREE;
        const auto [end, _] = std::mismatch(tree.begin(), tree.end(), self.begin(), self.end());
        if (end == tree.end()) places.push_back(VOXTIER_IMAGE_MODULE_IN_BUILD);
    }
    for (const std::string& place : places) {
        if (!std::filesystem::exists(place, ec)) continue;
        const std::string why = openModule(place, loaded.api);
        if (!why.empty()) loaded.failure = "voxtier's OpenImageIO module did not load: " + why;
        return loaded;
    }
    loaded.failure = "voxtier's OpenImageIO module " + std::string(detail::kImageLibraryFile) +
                     " is neither on the library path";
    for (const std::string& place : places) loaded.failure += " nor at " + place;
    return loaded;
}

const LoadedModule& module() {
    static const LoadedModule loaded = loadModule(); // once, thread-safe
    return loaded;
}

/// The module's functions; InputError naming `file` where it cannot be loaded.
const detail::ImageLibraryModule& api(const std::filesystem::path& file) {
    if (!module().api)
        throw InputError(file.string(), "",
                         "cannot read or write this format: " + module().failure);
    return *module().api;
}

/// The sRGB transfer function's inverse (IEC 61966-2-1): 8-bit sRGB code -> linear [0, 1].
float linearFromSrgb8(unsigned code) {
    const double c = double(code) / 255.0;
    return float(c <= 0.04045 ? c / 12.92 : std::pow((c + 0.055) / 1.055, 2.4));
}

/// Encodes in `file`'s format, then writes the file whole or not at all.
void writeEncoded(const std::filesystem::path& file, const detail::EncodeRequest& request) {
    std::vector<unsigned char> bytes;
    const std::string why = api(file).encode(file.string(), request, bytes);
    if (!why.empty()) throw InputError(file.string(), "", why);
    writeFileWhole(file, bytes);
}

} // namespace

namespace detail {

bool imageLibraryLoaded() {
    return module().api != nullptr;
}

std::string imageLibraryFailure() {
    return module().failure;
}

void writeWithImageLibrary(const std::filesystem::path& file, const Image& img, double zNear,
                           bool colorOnly) {
    EncodeRequest request;
    request.width = img.width;
    request.height = img.height;
    if (lowerExtension(file) != ".exr" || colorOnly) {
        request.channels = 4;
        request.pixels = img.color.data();
        writeEncoded(file, request);
        return;
    }
    // EXR: RGB decoded from the 8-bit sRGB colour to linear (EXR's convention, what
    // compositors assume) and premultiplied by alpha, + Z (view depth) + id.
    request.channels = 6;
    request.floats = true;
    request.channelNames = {"R", "G", "B", "A", "Z", "id"};
    request.zChannel = 4;
    request.alphaChannel = 3;
    request.colorSpace = "Linear";
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
    request.pixels = px.data();
    writeEncoded(file, request);
}

} // namespace detail

Image readColorImage(const std::filesystem::path& file) {
    detail::DecodedImage decoded;
    const std::string why = api(file).read(file.string(), decoded);
    if (!why.empty()) throw InputError(file.string(), "", why);
    Image img(decoded.width, decoded.height, 0);
    const std::size_t n = std::size_t(decoded.channels);
    for (std::size_t i = 0; i < img.pixelCount(); ++i) {
        unsigned ch[4] = {0, 0, 0, 255};
        for (std::size_t c = 0; c < std::min<std::size_t>(4, n); ++c)
            ch[c] = decoded.pixels[i * n + c];
        if (n < 3) ch[1] = ch[2] = ch[0];
        img.color[i] = packRgba(ch[0], ch[1], ch[2], ch[3]);
    }
    return img;
}

} // namespace voxtier
