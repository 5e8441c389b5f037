#include "core/file_write.hpp"

#include "core/error.hpp"

#include <sys/stat.h>

#include <atomic>
#include <cerrno>
#include <cstring>
#include <fcntl.h>
#include <system_error>
#include <unistd.h>

namespace voxtier {

namespace {

std::string osReason(int err) {
    return std::generic_category().message(err);
}

/// A name no other writer uses: the pid tells processes apart, the serial the writes of one.
std::filesystem::path tempNameFor(const std::filesystem::path& file) {
    static std::atomic<std::uint64_t> serial{0};
    std::filesystem::path tmp = file;
    tmp += std::string(kTempMarker) + std::to_string(::getpid()) + "-" + std::to_string(serial++);
    return tmp;
}

} // namespace

void writeFileWhole(const std::filesystem::path& file, std::span<const std::uint8_t> bytes,
                    bool sync) {
    const auto fail = [&](int err) {
        throw InputError(file.string(), "", "cannot write: " + osReason(err));
    };
    if (file.has_parent_path()) {
        std::error_code ec;
        std::filesystem::create_directories(file.parent_path(), ec);
        if (ec) fail(ec.value());
    }
    // A symbolic link stays one: the file it names is replaced. Something that is not a regular
    // file (/dev/stdout, a pipe) is written in place: a rename would replace the device node.
    // /dev/stdout and /dev/fd/N name whatever the descriptor is, a redirected regular file too:
    // written in place, as the shell's descriptor expects.
    const std::string name = file.lexically_normal().string();
    const bool descriptor = name == "/dev/stdout" || name == "/dev/stderr" ||
                            name.rfind("/dev/fd/", 0) == 0 || name.rfind("/proc/self/fd/", 0) == 0;
    struct stat st {};
    const bool special = descriptor || (::stat(file.c_str(), &st) == 0 && !S_ISREG(st.st_mode));
    std::filesystem::path target = file;
    std::error_code lec;
    if (!special && std::filesystem::is_symlink(file, lec)) {
        target = std::filesystem::weakly_canonical(file, lec);
        if (lec) fail(lec.value());
    }
    const std::filesystem::path tmp = special ? file : tempNameFor(target);
    // Appending: what the process wrote to a redirected stdout before stays.
    const int fd = special ? ::open(tmp.c_str(), O_WRONLY | O_APPEND | O_CLOEXEC)
                           : ::open(tmp.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0666);
    if (fd < 0) fail(errno);
    int err = 0;
    for (std::size_t done = 0; done < bytes.size() && !err;) {
        const ssize_t n = ::write(fd, bytes.data() + done, bytes.size() - done);
        if (n < 0 && errno == EINTR) continue;
        if (n < 0) err = errno;
        if (n == 0) err = ENOSPC; // write(2) returns 0 for a non-empty buffer only when full
        if (n > 0) done += std::size_t(n);
    }
    // EINVAL, EROFS: a pipe or a device, which have nothing to sync.
    if (!err && sync && ::fsync(fd) != 0 && errno != EINVAL && errno != EROFS) err = errno;
    // close(2) is where NFS reports a failed flush; its error counts like a write's.
    if (::close(fd) != 0 && !err && errno != EINTR) err = errno;
    if (special) {
        if (err) fail(err);
        return;
    }
    if (!err && ::rename(tmp.c_str(), target.c_str()) != 0) err = errno;
    if (err) {
        ::unlink(tmp.c_str());
        fail(err);
    }
}

bool sameOutputFile(const std::filesystem::path& a, const std::filesystem::path& b) {
    std::error_code ea, eb, ec;
    const std::filesystem::path ca = std::filesystem::weakly_canonical(a, ea);
    const std::filesystem::path cb = std::filesystem::weakly_canonical(b, eb);
    if (!ea && !eb && ca == cb) return true;
    if (a.lexically_normal() == b.lexically_normal()) return true;
    return std::filesystem::equivalent(a, b, ec) && !ec; // hard links: one inode
}

} // namespace voxtier
