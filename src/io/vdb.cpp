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

GsdVdbEncode plugin() {
    static GsdVdbEncode encode = nullptr;
    static std::once_flag once;
    std::call_once(once, [] {
        for (const std::string& path : plugin_candidates())
            if (void* handle = dlopen(path.c_str(), RTLD_NOW | RTLD_LOCAL)) {  // kept for the process's life
                encode = reinterpret_cast<GsdVdbEncode>(dlsym(handle, GSD_VDB_ENCODE_SYMBOL));
                if (encode) return;
                dlclose(handle);
            }
    });
    return encode;
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

}  // namespace gsd::io
