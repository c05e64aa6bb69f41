// .vdb output when gsd is built without OpenVDB (GSD_WITH_OPENVDB=OFF or libopenvdb-dev missing).
#include <gsd/io.hpp>

namespace gsd::io {

bool vdb_available() { return false; }

void write_vdb(const std::string& path, const GridSpec&, const std::vector<float>&, const VdbOptions&) {
    throw Error(path, "this gsd was built without OpenVDB (install libopenvdb-dev and rebuild); write .npy instead");
}

}  // namespace gsd::io
