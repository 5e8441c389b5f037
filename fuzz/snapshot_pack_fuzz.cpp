// libFuzzer target: the pack reader and writer the on-disk store uses (impostor_cache/
// snapshot_format.hpp) on arbitrary bytes, as a file: the bytes go into a memfd, which is read
// through a descriptor in bounded pieces, as the store reads a pack from its directory.
//
// What must hold, or it is a bug (abort, sanitizer report, allocation beyond the limits, hang):
// - the descriptor readers (readPackHead, readPackIndex) accept exactly what the in-memory
//   decoder (decodeSnapshotPack) accepts, with the same index;
// - each view is accepted alike by the checker in pieces (checkPackEntry, what a writer keeps of
//   an old pack), the reader (readPackEntry, what a render uses) and decodeSnapshotFile of its
//   bytes with the key the pack implies;
// - writing the accepted views to a new pack (writePackTo, what a writer does) gives a pack the
//   decoder accepts whole, holding exactly those views' bytes, and the very input when every
//   view was accepted.
#include "impostor_cache/snapshot_format.hpp"

#include <sys/mman.h>

#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <span>
#include <unistd.h>
#include <vector>

using namespace voxtier;

namespace {

int memfd(const char* name) {
    const int fd = ::memfd_create(name, MFD_CLOEXEC);
    if (fd < 0) std::abort();
    return fd;
}

void fill(int fd, const std::uint8_t* data, std::size_t size) {
    if (::ftruncate(fd, 0) != 0) std::abort();
    for (std::size_t done = 0; done < size;) {
        const ssize_t n = ::pwrite(fd, data + done, size - done, off_t(done));
        if (n <= 0) std::abort();
        done += std::size_t(n);
    }
}

std::vector<std::uint8_t> contents(int fd) {
    const off_t size = ::lseek(fd, 0, SEEK_END);
    std::vector<std::uint8_t> bytes(static_cast<std::size_t>(size));
    if (size > 0 && ::pread(fd, bytes.data(), bytes.size(), 0) != size) std::abort();
    return bytes;
}

template <class F> bool accepts(F&& f) {
    try {
        f();
        return true;
    } catch (const SnapshotFileError&) {
        return false;
    }
}

} // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
    static const int in = memfd("pack"), out = memfd("written");
    fill(in, data, size);
    const std::span<const std::uint8_t> bytes(data, size);

    PackHead head;
    PackIndex index;
    const bool readable = accepts([&] {
        head = readPackHead(in, size);
        index = readPackIndex(in, head);
    });
    DecodedSnapshotPack whole;
    if (accepts([&] { whole = decodeSnapshotPack(bytes); }) != readable) std::abort();
    if (!readable) return 0;
    if (whole.entries.size() != index.entries.size()) std::abort();

    std::vector<PackSource> kept;
    std::vector<std::span<const std::uint8_t>> keptBytes;
    for (std::size_t i = 0; i < index.entries.size(); ++i) {
        const PackIndexEntry& e = index.entries[i];
        if (!(whole.entries[i].view == e.view) || whole.entries[i].file.size() != e.bytes)
            std::abort();
        SnapshotFileKey key = head.frame;
        key.view = e.view;
        const bool inPieces = accepts([&] { checkPackEntry(in, e, key); });
        const bool read = accepts([&] {
            if (!(readPackEntry(in, e, key).key == key)) std::abort();
        });
        const bool decoded = accepts([&] {
            if (!(decodeSnapshotFile(whole.entries[i].file).key == key))
                throw SnapshotFileError("another key");
        });
        if (inPieces != read || read != decoded) std::abort();
        if (inPieces) {
            kept.push_back({e.view, {}, in, e.offset, e.bytes});
            keptBytes.push_back(whole.entries[i].file);
        }
    }

    if (::ftruncate(out, 0) != 0 || ::lseek(out, 0, SEEK_SET) != 0) std::abort();
    const std::size_t keptCount = kept.size();
    const std::uint64_t written = writePackTo(out, head.frame, std::move(kept));
    const std::vector<std::uint8_t> again = contents(out);
    if (again.size() != written) std::abort();
    const DecodedSnapshotPack rewritten = decodeSnapshotPack(again); // must not throw
    if (rewritten.entries.size() != keptCount) std::abort();
    for (std::size_t i = 0; i < keptCount; ++i)
        if (rewritten.entries[i].file.size() != keptBytes[i].size() ||
            std::memcmp(rewritten.entries[i].file.data(), keptBytes[i].data(),
                        keptBytes[i].size()) != 0)
            std::abort();
    if (keptCount == index.entries.size() &&
        (again.size() != size || (size > 0 && std::memcmp(again.data(), data, size) != 0)))
        std::abort();
    return 0;
}
