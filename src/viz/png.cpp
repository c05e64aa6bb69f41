// PNG output: encode in memory with stb_image_write, then write the bytes atomically.
#include <gsd/viz.hpp>

#include <stb/stb_image_write.h>  // the implementation is in libstb (Debian's stb package)

#include <atomic>
#include <cstdio>
#include <filesystem>
#include <unistd.h>

namespace gsd {
namespace {

// Writes `bytes` to a temporary file beside `path` and renames it over `path`, so readers see
// either the old file or the whole new one, never a partial PNG. (The io module's
// io::write_file_atomic does the same; this local copy keeps viz free of a link-time
// dependency on io.)
void write_file_atomically(const std::string& path, const std::string& bytes) {
    static std::atomic<unsigned> counter{0};
    const std::string temp = path + ".tmp." + std::to_string(::getpid()) + "." + std::to_string(counter++);
    std::FILE* f = std::fopen(temp.c_str(), "wb");
    if (!f) throw Error(path, "cannot create file (does the folder exist and is it writable?)");
    const bool written = std::fwrite(bytes.data(), 1, bytes.size(), f) == bytes.size();
    const bool closed = std::fclose(f) == 0;
    std::error_code ec;
    if (written && closed) std::filesystem::rename(temp, path, ec);
    if (!written || !closed || ec) {
        std::filesystem::remove(temp, ec);
        throw Error(path, "cannot write file");
    }
}

void append_to_string(void* context, void* data, int size) {
    static_cast<std::string*>(context)->append(static_cast<const char*>(data), std::size_t(size));
}

std::string encode_png(const Image& image) {
    std::string bytes;
    if (!stbi_write_png_to_func(append_to_string, &bytes, image.width, image.height, 3, image.rgb.data(),
                                image.width * 3))
        throw Error("png", "PNG encoding failed");
    return bytes;
}

}  // namespace

void write_png(const std::string& path, const Image& image) {
    if (image.width <= 0 || image.height <= 0)
        throw Error(path, "image to write has no pixels");
    if (image.rgb.size() != std::size_t(image.width) * std::size_t(image.height) * 3)
        throw Error(path, "image pixel buffer does not match width × height × 3");
    if (std::size_t(image.width) * 3 > std::size_t(INT32_MAX / 4))
        throw Error(path, "image too wide for PNG encoding");
    write_file_atomically(path, encode_png(image));
}

}  // namespace gsd
