// PNG output: encode in memory with stb_image_write, then write the bytes atomically.
#include <gsd/io.hpp>
#include <gsd/viz.hpp>

#include <stb/stb_image_write.h>  // the implementation is in libstb (Debian's stb package)

#include <cstdint>

namespace gsd {
namespace {

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
    io::write_file_atomic(path, encode_png(image));
}

}  // namespace gsd
