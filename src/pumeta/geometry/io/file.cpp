#include "pumeta/geometry/io/file.h"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <memory>
#include <new>

#include "pumeta/core/error.h"

namespace pumeta::io {

namespace fs = std::filesystem;

namespace {

struct FileCloser {
    void operator()(std::FILE* file) const { std::fclose(file); }
};
using FilePtr = std::unique_ptr<std::FILE, FileCloser>;

struct DescriptorCloser {
    int fd;
    ~DescriptorCloser() { ::close(fd); }
};

const char* file_kind(mode_t mode) {
    if (S_ISDIR(mode)) return "a directory";
    if (S_ISFIFO(mode)) return "a FIFO (named pipe)";
    if (S_ISCHR(mode)) return "a character device";
    if (S_ISBLK(mode)) return "a block device";
    if (S_ISSOCK(mode)) return "a socket";
    return "not a regular file";
}

}  // namespace

std::string read_whole_file(const std::string& path) {
    // Opened without blocking, so that a FIFO with no writer cannot hang the open; the type is
    // then checked on the open descriptor, so that nothing can swap the file in between.
    const int fd = ::open(path.c_str(), O_RDONLY | O_NONBLOCK | O_CLOEXEC);
    if (fd < 0) {
        if (errno == ENOENT) throw_input_error(path, "file not found");
        throw_input_error(path, "cannot open: {}", std::strerror(errno));
    }
    DescriptorCloser closer{fd};
    struct stat info {};
    if (::fstat(fd, &info) != 0) throw_input_error(path, "cannot stat: {}", std::strerror(errno));
    if (!S_ISREG(info.st_mode))
        throw_input_error(path, "is {}; only regular files are read", file_kind(info.st_mode));
    // The size is taken once; a file that grows meanwhile is read up to that size, one that
    // shrinks is read to its new end.
    const size_t size = static_cast<size_t>(info.st_size);
    if (size == 0) throw_input_error(path, "file is empty");
    std::string bytes;
    try {
        bytes.resize(size);
    } catch (const std::bad_alloc&) {
        throw_input_error(path, "{} bytes do not fit in memory", size);
    }
    size_t got = 0;
    while (got < size) {
        const ssize_t n = ::read(fd, bytes.data() + got, size - got);
        if (n < 0 && errno == EINTR) continue;
        if (n < 0) throw_input_error(path, "read error: {}", std::strerror(errno));
        if (n == 0) break;
        got += static_cast<size_t>(n);
    }
    bytes.resize(got);
    if (bytes.empty()) throw_input_error(path, "file is empty");
    return bytes;
}

void write_atomically(const std::string& path, std::string_view bytes) {
    const std::string temporary = path + ".tmp-" + std::to_string(::getpid());
    FilePtr file(std::fopen(temporary.c_str(), "wb"));
    if (!file) throw_input_error(path, "cannot write: {}", std::strerror(errno));
    const bool written = std::fwrite(bytes.data(), 1, bytes.size(), file.get()) == bytes.size();
    const int write_errno = errno;
    const bool closed = std::fclose(file.release()) == 0;
    std::error_code error;
    if (!written || !closed) {
        fs::remove(temporary, error);
        throw_input_error(path, "write failed: {}", std::strerror(written ? errno : write_errno));
    }
    fs::rename(temporary, path, error);
    if (error) {
        const std::string reason = error.message();
        fs::remove(temporary, error);
        throw_input_error(path, "cannot rename the temporary file into place: {}", reason);
    }
}

}  // namespace pumeta::io
