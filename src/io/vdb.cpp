// .vdb output: the checks here, the OpenVDB part in the plugin libgsd_vdb.so (vdb_plugin.h),
// loaded on first use so that programs that never write a .vdb never pay for OpenVDB.
#include <gsd/io.hpp>

#include "io/vdb_plugin.h"

#include <dlfcn.h>

#include <cmath>
#include <cstdlib>
#include <mutex>
#include <vector>

namespace gsd::io {

namespace {

// Where the plugin may be, in order: $GSD_VDB_PLUGIN; beside the module that holds this code
// (libgsd.so) or in ../lib from it (a program in bin/); the build tree; the install tree; the
// loader's search path.
std::vector<std::string> plugin_candidates() {
    std::vector<std::string> out;
    if (const char* env = std::getenv("GSD_VDB_PLUGIN"); env && *env) out.emplace_back(env);
    Dl_info info{};
    if (dladdr(reinterpret_cast<void*>(&plugin_candidates), &info) && info.dli_fname) {
        std::string dir = info.dli_fname;
        const auto slash = dir.find_last_of('/');
        dir = slash == std::string::npos ? "." : dir.substr(0, slash);
        out.push_back(dir + "/" GSD_VDB_PLUGIN_NAME);
        out.push_back(dir + "/../lib/" GSD_VDB_PLUGIN_NAME);
    }
#ifdef GSD_VDB_BUILD_PATH
    out.emplace_back(GSD_VDB_BUILD_PATH);
#endif
#ifdef GSD_VDB_INSTALL_PATH
    out.emplace_back(GSD_VDB_INSTALL_PATH);
#endif
    out.emplace_back(GSD_VDB_PLUGIN_NAME);
    return out;
}

struct Plugin {
    GsdVdbEncode encode = nullptr;
    GsdVdbDecode decode = nullptr;
    GsdVdbEncodeSparse encode_sparse = nullptr;
    GsdVdbMeshSparse mesh_sparse = nullptr;
};

const Plugin& plugin_functions() {
    static Plugin plugin;
    static std::once_flag once;
    std::call_once(once, [] {
        for (const std::string& path : plugin_candidates())
            if (void* handle = dlopen(path.c_str(), RTLD_NOW | RTLD_LOCAL)) {  // kept for the process's life
                plugin.encode = reinterpret_cast<GsdVdbEncode>(dlsym(handle, GSD_VDB_ENCODE_SYMBOL));
                plugin.decode = reinterpret_cast<GsdVdbDecode>(dlsym(handle, GSD_VDB_DECODE_SYMBOL));
                plugin.encode_sparse = reinterpret_cast<GsdVdbEncodeSparse>(dlsym(handle, GSD_VDB_ENCODE_SPARSE_SYMBOL));
                plugin.mesh_sparse = reinterpret_cast<GsdVdbMeshSparse>(dlsym(handle, GSD_VDB_MESH_SPARSE_SYMBOL));
                if (plugin.encode) return;
                dlclose(handle);
            }
    });
    return plugin;
}

GsdVdbEncode plugin() { return plugin_functions().encode; }

// read_vdb's buffer: the grid the plugin describes, if the memory budget allows it.
struct Decoded {
    GridSpec grid;
    std::vector<float> values;
    std::string refused;
};

float* allocate(void* context, const GsdVdbDense* d) {
    auto& out = *static_cast<Decoded*>(context);
    try {
        const double nodes = double(d->nx) * d->ny * d->nz;
        check_memory(4.0 * nodes, "grid", "a .vdb grid of " + std::to_string(d->nx) + "×" + std::to_string(d->ny) + "×" +
                                             std::to_string(d->nz) + " nodes");
        out.grid = GridSpec{d->nx, d->ny, d->nz,
                            Box{{d->lo[0], d->lo[1], d->lo[2]},
                                {d->lo[0] + d->step[0] * (d->nx - 1), d->lo[1] + d->step[1] * (d->ny - 1), d->lo[2] + d->step[2] * (d->nz - 1)}}};
        out.values.resize(std::size_t(nodes));
        return out.values.data();
    } catch (const Error& e) {
        out.refused = e.what();
        return nullptr;
    }
}

void append(void* context, const char* bytes, size_t size) { static_cast<std::string*>(context)->append(bytes, size); }

}  // namespace

bool vdb_available() { return plugin() != nullptr; }

void require_vdb(const std::string& path) {
    if (!vdb_available())
        throw Error(path, "this gsd cannot write .vdb: its OpenVDB plugin " GSD_VDB_PLUGIN_NAME
                          " was not found (gsd was built without libopenvdb-dev, or the plugin is not installed beside "
                          "libgsd; $GSD_VDB_PLUGIN may name it); write .npy instead");
}

std::pair<GridSpec, std::vector<float>> read_vdb(const std::string& path) {
    if (!vdb_available() || !plugin_functions().decode)
        throw Error(path, "this gsd cannot read .vdb: its OpenVDB plugin " GSD_VDB_PLUGIN_NAME
                          " was not found; read the grid as .npy instead");
    Decoded out;
    char error[512] = "";
    if (plugin_functions().decode(path.c_str(), allocate, &out, error, sizeof error) != 0)
        throw Error(path, !out.refused.empty() ? out.refused : std::string(error));
    if (out.grid.nx < 2 || out.grid.ny < 2 || out.grid.nz < 2)
        throw Error(path, "the grid's active voxels span fewer than 2 along an axis");
    out.grid.validate();
    for (float v : out.values)
        if (!std::isfinite(v)) throw Error(path, "the grid holds a value that is not finite");
    return {out.grid, std::move(out.values)};
}

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
    require_vdb(path);
    const GsdVdbEncode encode = plugin();
    const std::string creator = std::string("gsd ").append(version());
    GsdVdbGrid grid{g.nx, g.ny, g.nz, {g.box.lo[0], g.box.lo[1], g.box.lo[2]}, {step[0], step[1], step[2]}, values.data(),
                    o.name.c_str(), o.level_set ? 1 : 0, o.half_width, o.method.c_str(), creator.c_str()};
    std::string bytes;
    char error[512] = "";
    if (encode(&grid, append, &bytes, error, sizeof error) != 0) throw Error(path, error);
    write_file_atomic(path, bytes);
}

namespace {

// The checks both sparse functions make; the C view of the band.
GsdVdbSparse sparse_view(const std::string& where, const SparseLevelSet& b, const std::string& name, const std::string& method,
                         const std::string& creator) {
    if (b.ijk.size() != b.phi.size())
        throw Error(where, std::to_string(b.ijk.size()) + " lattice points for " + std::to_string(b.phi.size()) + " values");
    if (b.phi.empty()) throw Error(where, "the level set's band is empty");
    if (!(b.voxel > 0) || !std::isfinite(b.voxel) || !b.lo.allFinite()) throw Error(where, "the lattice needs a finite origin and voxel > 0");
    if (!(b.half_width >= 1 && b.half_width <= 1000)) throw Error("SparseLevelSet::half_width", "must be in [1, 1000] voxels");
    for (float v : b.phi)
        if (!std::isfinite(v)) throw Error(where, "a level set needs finite values");
    if (name.empty()) throw Error("VdbOptions::name", "must not be empty");
    return GsdVdbSparse{{b.lo[0], b.lo[1], b.lo[2]}, b.voxel, b.half_width, b.phi.size(), b.ijk.front().data(), b.phi.data(),
                        name.c_str(), method.c_str(), creator.c_str()};
}

struct MeshOut {
    PolygonMesh mesh;
};

void receive_mesh(void* context, const double* points, size_t point_count, const unsigned* triangles, size_t triangle_count) {
    PolygonMesh& m = static_cast<MeshOut*>(context)->mesh;
    m.vertices.resize(Eigen::Index(point_count), 3);
    for (size_t i = 0; i < point_count; ++i)
        for (int a = 0; a < 3; ++a) m.vertices(Eigen::Index(i), a) = points[3 * i + size_t(a)];
    m.indices.assign(triangles, triangles + 3 * triangle_count);
    m.offsets.resize(triangle_count + 1);
    for (size_t t = 0; t <= triangle_count; ++t) m.offsets[t] = std::uint32_t(3 * t);
}

}  // namespace

void write_vdb_sparse(const std::string& path, const SparseLevelSet& band, const VdbOptions& o) {
    require_vdb(path);
    const std::string creator = std::string("gsd ").append(version());
    const GsdVdbSparse view = sparse_view(path, band, o.name, o.method, creator);
    if (!plugin_functions().encode_sparse) throw Error(path, "the OpenVDB plugin found is older than this gsd (no sparse level sets)");
    std::string bytes;
    char error[512] = "";
    if (plugin_functions().encode_sparse(&view, append, &bytes, error, sizeof error) != 0) throw Error(path, error);
    write_file_atomic(path, bytes);
}

PolygonMesh mesh_level_set(const SparseLevelSet& band) {
    require_vdb("contour");
    const GsdVdbSparse view = sparse_view("contour", band, "surface", "", "gsd");
    if (!plugin_functions().mesh_sparse) throw Error("contour", "the OpenVDB plugin found is older than this gsd (no sparse level sets)");
    MeshOut out;
    char error[512] = "";
    if (plugin_functions().mesh_sparse(&view, receive_mesh, &out, error, sizeof error) != 0) throw Error("contour", error);
    return std::move(out.mesh);
}

}  // namespace gsd::io
