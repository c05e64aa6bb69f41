// libgsd_vdb.so: the OpenVDB half of .vdb output (Debian's libopenvdb-dev), loaded by libgsd on
// first use (src/io/vdb.cpp, vdb_plugin.h). A FloatGrid per scalar grid, with the transform that
// puts voxel (i, j, k) on gsd's node (i, j, k).
#include "io/vdb_plugin.h"

// OpenVDB's types keep default visibility: the plugin builds with hidden visibility, and a
// hidden copy of their type_info breaks the library's own casts (a segfault on write).
#pragma GCC visibility push(default)
#include <openvdb/io/File.h>
#include <openvdb/io/Stream.h>
#include <openvdb/openvdb.h>
#include <openvdb/tools/SignedFloodFill.h>
#include <openvdb/tools/VolumeToMesh.h>
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

// The file's float grid named "surface", else its first float grid.
openvdb::FloatGrid::Ptr float_grid(const char* path) {
    initialize_once();
    openvdb::io::File file(path);
    file.open();
    const openvdb::GridPtrVecPtr grids = file.getGrids();
    file.close();
    openvdb::FloatGrid::Ptr first;
    for (const openvdb::GridBase::Ptr& g : *grids)
        if (auto f = openvdb::gridPtrCast<openvdb::FloatGrid>(g)) {
            if (f->getName() == "surface") return f;
            if (!first) first = f;
        }
    if (!first) throw std::runtime_error("the file holds no float grid");
    return first;
}

void decode(const char* path, GsdVdbAllocate allocate, void* context) {
    const openvdb::FloatGrid::Ptr grid = float_grid(path);
    const openvdb::math::Transform& t = grid->transform();
    // Nodes on an axis-aligned lattice: a scale and a translation, nothing else.
    const openvdb::math::MapBase::ConstPtr map = t.baseMap();
    if (!(map->isType<openvdb::math::ScaleTranslateMap>() || map->isType<openvdb::math::UniformScaleTranslateMap>() ||
          map->isType<openvdb::math::ScaleMap>() || map->isType<openvdb::math::UniformScaleMap>() ||
          map->isType<openvdb::math::TranslationMap>()))
        throw std::runtime_error("the grid's transform is not an axis-aligned scale and translation (" + map->type() + ")");
    openvdb::CoordBBox box = grid->evalActiveVoxelBoundingBox();
    if (box.empty()) throw std::runtime_error("the grid has no active voxels");
    const bool level_set = grid->getGridClass() == openvdb::GRID_LEVEL_SET;
    if (level_set) box.expand(1);
    const openvdb::Coord dim = box.dim();
    GsdVdbDense dense{dim.x(), dim.y(), dim.z(), {}, {}, level_set ? 1 : 0};
    const openvdb::Vec3d lo = t.indexToWorld(box.min()), step = t.voxelSize();
    for (int a = 0; a < 3; ++a) {
        dense.lo[a] = lo[a];
        dense.step[a] = step[a];
    }
    float* values = allocate(context, &dense);
    if (!values) throw std::runtime_error("");  // refused: the caller knows why
    openvdb::FloatGrid::ConstAccessor acc = grid->getConstAccessor();
    std::size_t n = 0;
    for (int i = box.min().x(); i <= box.max().x(); ++i)
        for (int j = box.min().y(); j <= box.max().y(); ++j)
            for (int k = box.min().z(); k <= box.max().z(); ++k) values[n++] = acc.getValue(openvdb::Coord(i, j, k));
}

// A sparse level set as a FloatGrid: the band's points active, the inactive rest signed by a
// flood fill from the band (the band closes around every inside region it bounds).
openvdb::FloatGrid::Ptr sparse_grid(const GsdVdbSparse& b) {
    initialize_once();
    const float background = float(b.half_width * b.voxel);
    openvdb::FloatGrid::Ptr grid = openvdb::FloatGrid::create(background);
    grid->setTransform(openvdb::math::Transform::createLinearTransform(b.voxel));
    grid->transform().postTranslate(openvdb::Vec3d(b.lo[0], b.lo[1], b.lo[2]));
    grid->setGridClass(openvdb::GRID_LEVEL_SET);
    openvdb::FloatGrid::Accessor acc = grid->getAccessor();
    for (size_t n = 0; n < b.count; ++n)
        acc.setValue(openvdb::Coord(b.ijk[3 * n], b.ijk[3 * n + 1], b.ijk[3 * n + 2]), b.values[n]);
    openvdb::tools::signedFloodFill(grid->tree());
    return grid;
}

std::string encode_sparse(const GsdVdbSparse& b) {
    openvdb::FloatGrid::Ptr grid = sparse_grid(b);
    grid->setName(b.name);
    grid->setCreator(b.creator);
    if (b.method[0] != '\0') grid->insertMeta("gsd_method", openvdb::StringMetadata(b.method));
    std::ostringstream bytes(std::ios_base::binary);
    openvdb::io::Stream(bytes).write(openvdb::GridCPtrVec{grid});
    return bytes.str();
}

void mesh_sparse(const GsdVdbSparse& b, GsdVdbMeshSink sink, void* context) {
    const openvdb::FloatGrid::Ptr grid = sparse_grid(b);
    std::vector<openvdb::Vec3s> points;
    std::vector<openvdb::Vec3I> triangles;
    std::vector<openvdb::Vec4I> quads;
    openvdb::tools::volumeToMesh(*grid, points, triangles, quads, 0.0, 0.0);
    std::vector<double> xyz(3 * points.size());
    for (size_t i = 0; i < points.size(); ++i)
        for (int a = 0; a < 3; ++a) xyz[3 * i + size_t(a)] = double(points[i][a]);
    std::vector<unsigned> tris;
    tris.reserve(3 * triangles.size() + 6 * quads.size());
    // volumeToMesh faces the negative side (inside); gsd's meshes face outward: reversed.
    for (const openvdb::Vec3I& t : triangles) tris.insert(tris.end(), {t[0], t[2], t[1]});
    for (const openvdb::Vec4I& q : quads) tris.insert(tris.end(), {q[0], q[2], q[1], q[0], q[3], q[2]});
    sink(context, xyz.data(), points.size(), tris.data(), tris.size() / 3);
}

}  // namespace

extern "C" __attribute__((visibility("default"))) int gsd_vdb_encode_sparse(const GsdVdbSparse* band, GsdVdbSink sink,
                                                                             void* context, char* error, size_t error_size) {
    try {
        const std::string bytes = encode_sparse(*band);
        sink(context, bytes.data(), bytes.size());
        return 0;
    } catch (const std::exception& e) {  // nothing may cross the C boundary
        std::snprintf(error, error_size, "OpenVDB could not encode the level set: %s", e.what());
    } catch (...) {
        std::snprintf(error, error_size, "OpenVDB could not encode the level set");
    }
    return 1;
}

extern "C" __attribute__((visibility("default"))) int gsd_vdb_mesh_sparse(const GsdVdbSparse* band, GsdVdbMeshSink sink,
                                                                           void* context, char* error, size_t error_size) {
    try {
        mesh_sparse(*band, sink, context);
        return 0;
    } catch (const std::exception& e) {  // nothing may cross the C boundary
        std::snprintf(error, error_size, "OpenVDB could not mesh the level set: %s", e.what());
    } catch (...) {
        std::snprintf(error, error_size, "OpenVDB could not mesh the level set");
    }
    return 1;
}

extern "C" __attribute__((visibility("default"))) int gsd_vdb_decode(const char* path, GsdVdbAllocate allocate, void* context,
                                                                      char* error, size_t error_size) {
    try {
        decode(path, allocate, context);
        return 0;
    } catch (const std::exception& e) {  // nothing may cross the C boundary
        std::snprintf(error, error_size, "%s", e.what());
    } catch (...) {
        std::snprintf(error, error_size, "OpenVDB could not read the file");
    }
    return 1;
}

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
