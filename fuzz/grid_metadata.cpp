// Fuzzes io::read_grid_metadata, the JSON sidecar (GRID.npy.json) that `gsd contour` and
// `gsd slice` read for a grid's bounds (the whole input is the sidecar). What it accepts must
// describe a valid grid, and survive a write and a second read unchanged.
#include "fuzz_input.hpp"

#include <gsd/io.hpp>

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
    if (size > gsd_fuzz::kMaxInput) return 0;
    const std::string sidecar = gsd_fuzz::write_input(data, size, ".npy.json");
    const std::string grid = sidecar.substr(0, sidecar.size() - 5);  // input.npy
    try {
        const std::optional<gsd::io::GridMetadata> meta = gsd::io::read_grid_metadata(grid);
        if (!meta) __builtin_trap();  // the sidecar exists: "none" would be wrong
        meta->grid.validate();         // accepted means valid
        if (meta->components != 1 && meta->components != 3) __builtin_trap();
        const std::string copy = gsd_fuzz::temp_dir() + "/copy.npy";
        gsd::io::write_grid_metadata(copy, *meta);
        const std::optional<gsd::io::GridMetadata> again = gsd::io::read_grid_metadata(copy);
        if (!again || again->grid.nx != meta->grid.nx || again->grid.ny != meta->grid.ny ||
            again->grid.nz != meta->grid.nz || again->grid.box.lo != meta->grid.box.lo ||
            again->grid.box.hi != meta->grid.box.hi || again->components != meta->components ||
            again->method != meta->method || again->command != meta->command)
            __builtin_trap();
    } catch (const gsd::Error&) {
    }
    return 0;
}
