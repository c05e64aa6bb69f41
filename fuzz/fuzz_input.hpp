// What every fuzz target shares (docs/io.md, "Fuzzing"). The readers take paths, so each input
// is written to a file with the right extension in a folder of this process, gsd-fuzz-<pid>-*
// in $TMPDIR, else /dev/shm, else /tmp (made once, reused, removed at a normal exit;
// scripts/fuzz.sh removes it after a crash). Only gsd::Error may leave a reader: the targets
// catch that and nothing else, so any other exception escapes, aborts, and libFuzzer records
// the input.
#pragma once

#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <string>

#include <fcntl.h>
#include <unistd.h>

namespace gsd_fuzz {

/// Inputs larger than this return at once: every reader is linear, so 1 MiB finds what 100 MiB does.
inline constexpr std::size_t kMaxInput = std::size_t(1) << 20;

inline void remove_temp_dir();

/// The folder, made on first use. Allocated once and never freed, so that the exit handler
/// that removes it never sees a destroyed string (static destructors and atexit interleave).
inline const std::string& temp_dir() {
    static const std::string* dir = [] {
        // $TMPDIR, else /dev/shm: on a disk (ext4), rewriting a truncated file waits for the
        // disk at close, which cuts the executions per second by ten.
        const char* base = std::getenv("TMPDIR");
        if (!base || !*base) base = ::access("/dev/shm", W_OK) == 0 ? "/dev/shm" : "/tmp";
        auto* d = new std::string(std::string(base) + "/gsd-fuzz-" + std::to_string(::getpid()) + "-XXXXXX");
        if (!mkdtemp(d->data())) {
            std::perror("gsd-fuzz: mkdtemp");
            std::abort();
        }
        std::atexit(remove_temp_dir);
        return d;
    }();
    return *dir;
}

inline void remove_temp_dir() {
    // Only the names write_input makes; the folder is ours (mkdtemp).
    for (const char* ext : {".ply", ".xyz", ".pc", ".obj", ".npy", ".off", ".stl", ".tori", ".safetensors", ".txt", ".npy.json"})
        ::unlink((temp_dir() + "/input" + ext).c_str());
    ::unlink((temp_dir() + "/copy.npy.json").c_str());
    ::rmdir(temp_dir().c_str());
}

/// Writes the bytes to <temp dir>/input<ext> (replacing the previous input) and returns the path.
inline std::string write_input(const std::uint8_t* data, std::size_t size, const char* ext) {
    const std::string path = temp_dir() + "/input" + ext;
    const int fd = ::open(path.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0600);
    if (fd < 0) {
        std::perror(("gsd-fuzz: " + path).c_str());
        std::abort();
    }
    while (size > 0) {
        const ssize_t n = ::write(fd, data, size);
        if (n <= 0) {
            std::perror(("gsd-fuzz: " + path).c_str());
            std::abort();
        }
        data += n;
        size -= std::size_t(n);
    }
    ::close(fd);
    return path;
}

}  // namespace gsd_fuzz
