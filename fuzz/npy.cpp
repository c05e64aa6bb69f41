// Fuzzes the .npy readers: io::read_npy, io::read_queries and io::read_grid on the same file
// (the whole input is the file, extension .npy). Point clouds from .npy are in point_cloud.cpp.
#include "fuzz_input.hpp"

#include <gsd/io.hpp>

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
    if (size > gsd_fuzz::kMaxInput) return 0;
    const std::string path = gsd_fuzz::write_input(data, size, ".npy");
    try {
        const gsd::io::NpyArray a = gsd::io::read_npy(path);
        std::size_t product = 1;
        for (std::size_t d : a.shape) product *= d;
        if (product != a.size()) __builtin_trap();  // the shape must describe the data read
    } catch (const gsd::Error&) {
    }
    try {
        (void)gsd::io::read_queries(path);
    } catch (const gsd::Error&) {
    }
    try {
        (void)gsd::io::read_grid(path);
    } catch (const gsd::Error&) {
    }
    return 0;
}
