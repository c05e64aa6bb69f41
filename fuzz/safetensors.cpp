// Fuzzes loading TorusNet weights (.safetensors; the whole input is the file) through the public
// gsd::TorusNet constructor, which parses the container and checks names, shapes, dtypes,
// offsets, metadata and values. A model that loads reports its description; nothing is run.
#include "fuzz_input.hpp"

#include <gsd/pat.hpp>

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
    if (size > gsd_fuzz::kMaxInput) return 0;
    gsd::TorusNetOptions options;
    options.model = gsd_fuzz::write_input(data, size, ".safetensors");
    options.device = "cpu";
    try {
        const gsd::TorusNet net(options);
        if (net.k() < 2) __builtin_trap();  // the loader promises k >= 2
        (void)net.description();
    } catch (const gsd::Error&) {
    }
    return 0;
}
