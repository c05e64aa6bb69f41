// Fuzzes io::read_curve_file. The first input byte picks the extension (byte % 2: .txt, the
// curve text format; .obj, its l/p lines); the rest is the file. The same file is then read
// against a fixed mesh, the one `gsd mesh torus -r 16` writes (what the seed curves were drawn
// on), as curves (read_surface_curves) and as points (read_surface_points), and every node is
// placed on the mesh.
#include "fuzz_input.hpp"

#include <gsd/io.hpp>
#include <gsd/shapes.hpp>
#include <gsd/surface.hpp>

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
    static const char* const kExt[] = {".txt", ".obj"};
    static const gsd::SurfaceMesh mesh(gsd::shapes::mesh(*gsd::shapes::by_name("torus"), 16));
    if (size < 1 || size > gsd_fuzz::kMaxInput) return 0;
    const std::string path = gsd_fuzz::write_input(data + 1, size - 1, kExt[data[0] % 2]);
    try {
        (void)gsd::io::read_curve_file(path);
    } catch (const gsd::Error&) {
        return 0;  // the mesh-aware readers parse with the same code
    }
    try {
        const gsd::SurfaceSources sources = gsd::read_surface_curves(path, mesh);
        for (const gsd::SurfaceCurve& c : sources.curves)
            for (const gsd::SurfacePoint& p : c.nodes) (void)gsd::position(mesh, p);
    } catch (const gsd::Error&) {
    }
    try {
        for (const gsd::SurfacePoint& p : gsd::read_surface_points(path, mesh)) (void)gsd::position(mesh, p);
    } catch (const gsd::Error&) {
    }
    return 0;
}
