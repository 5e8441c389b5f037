#pragma once
// Output files that are whole or absent (CONTRACT.md §1). A file is written under a temporary name
// in its own folder (so the rename cannot cross a filesystem), every write, the fsync and the
// close are checked, and only then is it renamed over the final name: a full disk, a
// permission, a quota or a kill part-way leaves the previous file (or none) under the final
// name, never a truncated one that looks valid.
#include <cstdint>
#include <filesystem>
#include <span>
#include <string>
#include <string_view>

namespace voxtier {

/// The temporary names writeFileWhole uses for `file` start with this (then the file name, the
/// pid and a process-wide serial). A temporary whose writer died is left behind; a later run of
/// the same output replaces only its own.
inline constexpr std::string_view kTempMarker = ".tmp-";

/// Writes `bytes` to `file` whole or not at all (creating its folder). On failure removes the
/// temporary and throws InputError(file, "", "cannot write: <OS reason>"), e.g. "No space left
/// on device" or "Permission denied". `sync`: fsync before the close, so that a filesystem that
/// reports a full disk or a lost server only at writeback (NFS, delayed allocation) reports it
/// here. A symbolic link keeps pointing at the (replaced) file; a target that exists and is not
/// a regular file (a named pipe, a device), or a descriptor's name (/dev/stdout, /dev/stderr,
/// /dev/fd/N, /proc/self/fd/N, even when redirected to a file), is appended to in place.
void writeFileWhole(const std::filesystem::path& file, std::span<const std::uint8_t> bytes,
                    bool sync = true);
inline void writeFileWhole(const std::filesystem::path& file, std::string_view text,
                           bool sync = true) {
    writeFileWhole(file,
                   std::span<const std::uint8_t>(reinterpret_cast<const std::uint8_t*>(text.data()),
                                                 text.size()),
                   sync);
}

/// Whether two output paths name the same file (the same path after normalisation, or, when
/// both exist, the same inode): two outputs of one run must not overwrite each other.
bool sameOutputFile(const std::filesystem::path& a, const std::filesystem::path& b);

} // namespace voxtier
