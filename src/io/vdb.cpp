// .vdb output through OpenVDB (Debian's libopenvdb-dev): a FloatGrid per scalar grid, with the
// transform that puts voxel (i, j, k) on gsd's node (i, j, k).
#include <gsd/io.hpp>

// OpenVDB's types must keep default visibility in this file: gsd builds with hidden visibility,
// and a hidden copy of their type_info breaks the library's own casts (a segfault on write).
#pragma GCC visibility push(default)
#include <openvdb/io/Stream.h>
#include <openvdb/openvdb.h>
#pragma GCC visibility pop

#include <cmath>
#include <mutex>
#include <sstream>

namespace gsd::io {

namespace {

void initialize_once() {
    static std::once_flag once;
    std::call_once(once, [] { openvdb::initialize(); });
}

openvdb::math::Transform::Ptr node_transform(const GridSpec& g, const Eigen::Vector3d& step) {
    const openvdb::Vec3d scale(step[0], step[1], step[2]), lo(g.box.lo[0], g.box.lo[1], g.box.lo[2]);
    return std::make_shared<openvdb::math::Transform>(std::make_shared<openvdb::math::ScaleTranslateMap>(scale, lo));
}

}  // namespace

bool vdb_available() { return true; }

void write_vdb(const std::string& path, const GridSpec& g, const std::vector<float>& values, const VdbOptions& o) {
    g.validate();
    if (values.size() != g.node_count())
        throw Error(path, std::to_string(values.size()) + " values for a grid of " + std::to_string(g.node_count()) + " nodes");
    for (float v : values)
        if (!std::isfinite(v)) throw Error(path, "a .vdb grid needs finite values");
    if (o.name.empty()) throw Error("VdbOptions::name", "must not be empty");
    if (o.level_set && !(o.half_width >= 1 && o.half_width <= 1000))
        throw Error("VdbOptions::half_width", "must be in [1, 1000] voxels");
    const Eigen::Vector3d step = g.box.extent().cwiseQuotient(Eigen::Vector3d(g.nx - 1, g.ny - 1, g.nz - 1));
    if (o.level_set && (std::abs(step[1] / step[0] - 1) > 1e-6 || std::abs(step[2] / step[0] - 1) > 1e-6))
        throw Error(path, "a level set needs cubic voxels, and this grid's spacing is " + std::to_string(step[0]) + ", " +
                              std::to_string(step[1]) + ", " + std::to_string(step[2]) +
                              " (equal extents per node count, e.g. the default cubic bounds, give cubes)");
    initialize_once();

    const float background = o.level_set ? float(o.half_width * step[0]) : 0.0f;
    openvdb::FloatGrid::Ptr grid = openvdb::FloatGrid::create(background);
    grid->setTransform(node_transform(g, step));
    grid->setName(o.name);
    grid->setGridClass(o.level_set ? openvdb::GRID_LEVEL_SET : openvdb::GRID_UNKNOWN);
    grid->setCreator(std::string("gsd ").append(version()));
    if (!o.method.empty()) grid->insertMeta("gsd_method", openvdb::StringMetadata(o.method));
    openvdb::FloatGrid::Accessor acc = grid->getAccessor();
    std::size_t n = 0;
    for (int i = 0; i < g.nx; ++i)
        for (int j = 0; j < g.ny; ++j)
            for (int k = 0; k < g.nz; ++k, ++n) {
                const openvdb::Coord ijk(i, j, k);
                const float v = values[n];
                if (!o.level_set || std::abs(v) < background) acc.setValue(ijk, v);
                // Outside the band: inactive, ±background by the sign gsd computed there (no
                // flood fill: a band cut by the grid's box would leave its sign to guesswork).
                else acc.setValueOff(ijk, v < 0 ? -background : background);
            }
    grid->pruneGrid(0.0f);  // uniform regions (the inactive outside and inside) become tiles

    std::ostringstream bytes(std::ios_base::binary);
    try {
        openvdb::io::Stream(bytes).write(openvdb::GridCPtrVec{grid});
    } catch (const openvdb::Exception& e) {
        throw Error(path, std::string("OpenVDB could not encode the grid: ") + e.what());
    }
    write_file_atomic(path, bytes.str());
}

}  // namespace gsd::io
