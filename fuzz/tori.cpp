// Fuzzes load_tori (the .tori file of `gsd pat fit`; the whole input is the file). Tori that
// load are turned into a TorusField on the CPU and evaluated, with gradient, at a few points:
// the center and corners of their bounding box.
#include "fuzz_input.hpp"

#include <gsd/pat.hpp>

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
    if (size > gsd_fuzz::kMaxInput) return 0;
    const std::string path = gsd_fuzz::write_input(data, size, ".tori");
    try {
        gsd::FittedTori tori = gsd::load_tori(path);
        const gsd::Box box = gsd::bounding_box(tori.points);
        gsd::Points queries(3, 3);
        queries.row(0) = (0.5 * (box.lo + box.hi)).transpose();
        queries.row(1) = box.lo.transpose();
        queries.row(2) = box.hi.transpose();
        gsd::BlendOptions options;
        options.device = "cpu";
        const gsd::TorusField field(std::move(tori), options);
        (void)field.evaluate(queries, /*with_gradient=*/true);
    } catch (const gsd::Error&) {
    }
    return 0;
}
