// Fuzzes io::read_point_cloud. The first input byte picks the extension (byte % 5: .ply .xyz
// .pc .obj .npy); the rest is the file. (.xyzn and .txt share the .xyz parser.) A cloud that
// reads (it has passed gsd::validate) then goes through its bounding cube and a k-d tree.
#include "fuzz_input.hpp"

#include <gsd/io.hpp>
#include <gsd/spatial.hpp>

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
    static const char* const kExt[] = {".ply", ".xyz", ".pc", ".obj", ".npy"};
    if (size < 1 || size > gsd_fuzz::kMaxInput) return 0;
    const std::string path = gsd_fuzz::write_input(data + 1, size - 1, kExt[data[0] % 5]);
    try {
        const gsd::PointCloud cloud = gsd::io::read_point_cloud(path);
        (void)gsd::padded_cube(gsd::bounding_box(cloud.points));
        (void)gsd::mean_spacing(cloud.points);
    } catch (const gsd::Error&) {
    }
    return 0;
}
