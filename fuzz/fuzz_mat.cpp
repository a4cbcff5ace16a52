// libFuzzer target: MATLAB .mat files through feedid's reader (read_mat), which hands the file to libmatio (and, for
// v7.3, HDF5) and turns what it gets back into channels. Read or InputError; anything else is a bug.
//
// libmatio opens files by name only, so each input goes into an anonymous in-memory file (memfd) that is opened as
// /proc/self/fd/N: no disk, nothing left behind, and one file reused for every input.
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <string>

#include <sys/mman.h>
#include <unistd.h>

#include "feedid/core/error.hpp"
#include "feedid/io/mat.hpp"

namespace {
int memory_file() {
    static const int descriptor = [] {
        const int fd = ::memfd_create("fuzz.mat", MFD_CLOEXEC);
        if (fd < 0) {
            std::perror("memfd_create");
            std::abort();
        }
        return fd;
    }();
    return descriptor;
}
}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
    const int fd = memory_file();
    if (::ftruncate(fd, 0) != 0) std::abort();
    for (std::size_t written = 0; written < size;) {
        const auto n = ::pwrite(fd, data + written, size - written, static_cast<off_t>(written));
        if (n <= 0) std::abort();
        written += static_cast<std::size_t>(n);
    }
    static const std::string path = "/proc/self/fd/" + std::to_string(fd);
    try {
        (void)feedid::read_mat(path);
    } catch (const feedid::InputError&) {}
    return 0;
}
