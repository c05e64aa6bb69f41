// Fuzzes io::read_mesh. The first input byte picks the extension (byte % 4: .obj .off .stl .ply);
// the rest is the file. A mesh that reads is validated again and turned into a gsd::SurfaceMesh
// (fan triangulation, edge numbering, topology), whose summary is computed.
#include "fuzz_input.hpp"

#include <gsd/io.hpp>
#include <gsd/surface.hpp>

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
    static const char* const kExt[] = {".obj", ".off", ".stl", ".ply"};
    if (size < 1 || size > gsd_fuzz::kMaxInput) return 0;
    const std::string path = gsd_fuzz::write_input(data + 1, size - 1, kExt[data[0] % 4]);
    try {
        gsd::PolygonMesh mesh = gsd::io::read_mesh(path);
        (void)gsd::io::file_has_faces(path);
        gsd::validate(mesh, path);
        const gsd::SurfaceMesh surface(std::move(mesh), path);
        (void)surface.summary();
    } catch (const gsd::Error&) {
    }
    return 0;
}
