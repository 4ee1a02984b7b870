#include "pumeta/geometry/io/file.h"

#include <unistd.h>

#include <cerrno>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <memory>

#include "pumeta/core/error.h"

namespace pumeta::io {

namespace fs = std::filesystem;

namespace {

struct FileCloser {
    void operator()(std::FILE* file) const { std::fclose(file); }
};
using FilePtr = std::unique_ptr<std::FILE, FileCloser>;

}  // namespace

std::string read_whole_file(const std::string& path) {
    std::error_code error;
    const fs::file_status status = fs::status(path, error);
    if (!fs::exists(status)) throw_input_error(path, "file not found");
    if (fs::is_directory(status)) throw_input_error(path, "is a directory, not a file");
    FilePtr file(std::fopen(path.c_str(), "rb"));
    if (!file) throw_input_error(path, "cannot open: {}", std::strerror(errno));
    // One read of the reported size, then on to the end: pipes and /proc files report none.
    std::string bytes;
    const uintmax_t size = fs::file_size(path, error);
    if (!error && size > 0) {
        bytes.resize(size);
        bytes.resize(std::fread(bytes.data(), 1, size, file.get()));
    }
    char buffer[1 << 16];
    size_t got;
    while ((got = std::fread(buffer, 1, sizeof(buffer), file.get())) > 0) bytes.append(buffer, got);
    if (std::ferror(file.get())) throw_input_error(path, "read error: {}", std::strerror(errno));
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
