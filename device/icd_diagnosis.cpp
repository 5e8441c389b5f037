#include "device/icd_diagnosis.hpp"

#include "device/vulkan_options.hpp"

#include <nlohmann/json.hpp>

#include <algorithm>
#include <cstdlib>
#include <dlfcn.h>
#include <filesystem>
#include <fstream>
#include <system_error>

namespace voxtier {

namespace {

namespace fs = std::filesystem;

std::string env(const char* name) {
    const char* v = std::getenv(name);
    return v ? std::string(v) : std::string();
}

std::vector<std::string> splitColons(const std::string& s) {
    std::vector<std::string> parts;
    std::size_t start = 0;
    while (start <= s.size()) {
        const std::size_t colon = s.find(':', start);
        const std::size_t end = colon == std::string::npos ? s.size() : colon;
        if (end > start) parts.push_back(s.substr(start, end - start));
        if (colon == std::string::npos) break;
        start = colon + 1;
    }
    return parts;
}

/// A file as itself; a folder as its *.json files in name order (the loader's reading).
void addManifests(const std::string& path, std::vector<std::string>& out) {
    std::error_code ec;
    if (fs::is_directory(path, ec)) {
        std::vector<std::string> files;
        for (const auto& e : fs::directory_iterator(path, ec))
            if (e.path().extension() == ".json") files.push_back(e.path().string());
        std::sort(files.begin(), files.end());
        out.insert(out.end(), files.begin(), files.end());
    } else if (fs::exists(path, ec)) {
        out.push_back(path);
    }
}

/// The word-size mismatch the loader also skips without a word.
bool otherWordSize(const std::string& reason) {
    return reason.find("wrong ELF class") != std::string::npos;
}

} // namespace

std::vector<std::string> icdManifestFiles() {
    std::vector<std::string> out;
    std::string exclusive = env("VK_DRIVER_FILES");
    if (exclusive.empty()) exclusive = env("VK_ICD_FILENAMES");
    if (!exclusive.empty()) {
        for (const std::string& p : splitColons(exclusive)) addManifests(p, out);
        return out;
    }
    for (const std::string& p : splitColons(env("VK_ADD_DRIVER_FILES"))) addManifests(p, out);
    const std::string home = env("HOME");
    std::vector<std::string> roots;
    const std::string configHome = env("XDG_CONFIG_HOME");
    if (!configHome.empty())
        roots.push_back(configHome);
    else if (!home.empty())
        roots.push_back(home + "/.config");
    const std::string configDirs = env("XDG_CONFIG_DIRS");
    for (const std::string& d : splitColons(configDirs.empty() ? "/etc/xdg" : configDirs))
        roots.push_back(d);
    roots.push_back("/etc");
    const std::string dataHome = env("XDG_DATA_HOME");
    if (!dataHome.empty())
        roots.push_back(dataHome);
    else if (!home.empty())
        roots.push_back(home + "/.local/share");
    const std::string dataDirs = env("XDG_DATA_DIRS");
    for (const std::string& d :
         splitColons(dataDirs.empty() ? "/usr/local/share:/usr/share" : dataDirs))
        roots.push_back(d);
    std::vector<std::string> seenRoots;
    for (const std::string& r : roots) {
        if (std::find(seenRoots.begin(), seenRoots.end(), r) != seenRoots.end()) continue;
        seenRoots.push_back(r);
        addManifests(r + "/vulkan/icd.d", out);
    }
    return out;
}

std::vector<IcdLoadFailure> findIcdLoadFailures(const std::vector<std::string>& manifests) {
    std::vector<IcdLoadFailure> failures;
    for (const std::string& manifest : manifests) {
        std::string library;
        try {
            std::ifstream in(manifest);
            if (!in) {
                failures.push_back({manifest, "", "cannot be opened"});
                continue;
            }
            const nlohmann::json j = nlohmann::json::parse(in);
            // A manifest without ICD.library_path is skipped by the loader too: not a driver.
            if (!j.is_object() || !j.contains("ICD") || !j["ICD"].is_object() ||
                !j["ICD"].contains("library_path") || !j["ICD"]["library_path"].is_string())
                continue;
            library = j["ICD"]["library_path"].get<std::string>();
        } catch (const std::exception& e) {
            failures.push_back({manifest, "", std::string("is not valid JSON: ") + e.what()});
            continue;
        }
        std::string path = library;
        if (library.find('/') != std::string::npos && fs::path(library).is_relative())
            path = (fs::path(manifest).parent_path() / library).lexically_normal().string();
        dlerror(); // clear
        if (void* handle = dlopen(path.c_str(), RTLD_NOW | RTLD_LOCAL)) {
            dlclose(handle);
            continue;
        }
        const char* why = dlerror();
        std::string reason = why ? why : "dlopen failed";
        if (otherWordSize(reason)) continue;
        failures.push_back({manifest, library, std::move(reason)});
    }
    return failures;
}

std::string noVulkanDeviceMessage() {
    const std::vector<IcdLoadFailure> failures = findIcdLoadFailures(icdManifestFiles());
    if (failures.empty()) return kNoVulkanDeviceMessage;
    std::string msg = "no Vulkan device:";
    constexpr std::size_t kShown = 3;
    for (std::size_t i = 0; i < failures.size() && i < kShown; ++i) {
        const IcdLoadFailure& f = failures[i];
        msg += i == 0 ? " " : "; ";
        if (f.library.empty())
            msg += "the driver manifest " + f.manifest + " " + f.reason;
        else
            msg +=
                "the driver of " + f.manifest + " (" + f.library + ") does not load: " + f.reason;
    }
    if (failures.size() > kShown)
        msg += "; and " + std::to_string(failures.size() - kShown) + " more";
    // dlerror text is one line; keep the message one line whatever a manifest contains.
    std::replace(msg.begin(), msg.end(), '\n', ' ');
    return msg;
}

} // namespace voxtier
