// libgsd_vdb.so: the OpenVDB half of .vdb output (Debian's libopenvdb-dev), loaded by libgsd on
// first use (src/io/vdb.cpp, vdb_plugin.h). A FloatGrid per scalar grid, with the transform that
// puts voxel (i, j, k) on gsd's node (i, j, k).
#include "io/vdb_plugin.h"

// OpenVDB's types keep default visibility: the plugin builds with hidden visibility, and a
// hidden copy of their type_info breaks the library's own casts (a segfault on write).
#pragma GCC visibility push(default)
#include <openvdb/io/Stream.h>
#include <openvdb/openvdb.h>
#pragma GCC visibility pop

#include <cmath>
#include <cstdio>
#include <exception>
#include <mutex>
#include <sstream>
#include <string>

namespace {

void initialize_once() {
    static std::once_flag once;
    std::call_once(once, [] { openvdb::initialize(); });
}

std::string encode(const GsdVdbGrid& g) {
    initialize_once();
    const float background = g.level_set ? float(g.half_width * g.step[0]) : 0.0f;
    openvdb::FloatGrid::Ptr grid = openvdb::FloatGrid::create(background);
    const openvdb::Vec3d scale(g.step[0], g.step[1], g.step[2]), lo(g.lo[0], g.lo[1], g.lo[2]);
    grid->setTransform(std::make_shared<openvdb::math::Transform>(std::make_shared<openvdb::math::ScaleTranslateMap>(scale, lo)));
    grid->setName(g.name);
    grid->setGridClass(g.level_set ? openvdb::GRID_LEVEL_SET : openvdb::GRID_UNKNOWN);
    grid->setCreator(g.creator);
    if (g.method[0] != '\0') grid->insertMeta("gsd_method", openvdb::StringMetadata(g.method));
    openvdb::FloatGrid::Accessor acc = grid->getAccessor();
    std::size_t n = 0;
    for (int i = 0; i < g.nx; ++i)
        for (int j = 0; j < g.ny; ++j)
            for (int k = 0; k < g.nz; ++k, ++n) {
                const openvdb::Coord ijk(i, j, k);
                const float v = g.values[n];
                if (!g.level_set || std::abs(v) < background) acc.setValue(ijk, v);
                // Outside the band: inactive, ±background by the sign gsd computed there (no
                // flood fill: a band cut by the grid's box would leave its sign to guesswork).
                else acc.setValueOff(ijk, v < 0 ? -background : background);
            }
    grid->pruneGrid(0.0f);  // uniform regions (the inactive outside and inside) become tiles
    std::ostringstream bytes(std::ios_base::binary);
    openvdb::io::Stream(bytes).write(openvdb::GridCPtrVec{grid});
    return bytes.str();
}

}  // namespace

extern "C" __attribute__((visibility("default"))) int gsd_vdb_encode(const GsdVdbGrid* grid, GsdVdbSink sink, void* context,
                                                                      char* error, size_t error_size) {
    try {
        const std::string bytes = encode(*grid);
        sink(context, bytes.data(), bytes.size());
        return 0;
    } catch (const std::exception& e) {  // nothing may cross the C boundary
        std::snprintf(error, error_size, "OpenVDB could not encode the grid: %s", e.what());
    } catch (...) {
        std::snprintf(error, error_size, "OpenVDB could not encode the grid");
    }
    return 1;
}
