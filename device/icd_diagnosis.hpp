#pragma once
// Why there is no Vulkan device, when the answer is a driver that is installed but does not load
// (issue 35, Deliver 6). On the H100 machine NVIDIA's driver manifest was present but its library
// needed glvnd's libGLdispatch, the loader skipped it in silence, and the message said to install
// lavapipe. Here the manifests the loader would read are read again and each driver library is
// dlopen'ed the way the loader does, so the message can name the one that failed and why.
//
// Manifests searched, in the loader's order (Linux): VK_DRIVER_FILES, else VK_ICD_FILENAMES
// (colon-separated files or folders; nothing else is searched when either is set); otherwise
// VK_ADD_DRIVER_FILES, then vulkan/icd.d under $XDG_CONFIG_HOME (~/.config), $XDG_CONFIG_DIRS
// (/etc/xdg), /etc, $XDG_DATA_HOME (~/.local/share) and $XDG_DATA_DIRS (/usr/local/share:
// /usr/share). A library_path with a slash is relative to its manifest's folder; a bare name
// goes through the dynamic linker's search, as in the loader. Libraries of the other word size
// (a 32-bit driver's manifest on a 64-bit system, which the loader skips too) are not failures.
#include <string>
#include <vector>

namespace voxtier {

struct IcdLoadFailure {
    std::string manifest; ///< the manifest file
    std::string library; ///< its ICD.library_path as written, or "" when the manifest is unreadable
    std::string reason;  ///< dlerror()'s text, or why the manifest could not be read
};

/// The driver manifest files the loader would read, in its order, from the environment.
std::vector<std::string> icdManifestFiles();
/// The manifests among `manifests` whose driver library does not load (or that cannot be read).
/// Never throws.
std::vector<IcdLoadFailure> findIcdLoadFailures(const std::vector<std::string>& manifests);

/// The one-line message for "no usable Vulkan device": kNoVulkanDeviceMessage when every driver
/// manifest's library loads (or there is none), otherwise it names the failing drivers, e.g.
/// "no Vulkan device: the driver of /usr/share/vulkan/icd.d/nvidia_icd.json (libGLX_nvidia.so.0)
/// does not load: libGLdispatch.so.0: cannot open shared object file: No such file or directory".
std::string noVulkanDeviceMessage();

} // namespace voxtier
