// The io module's public entry points: pick the format by extension, read the whole file
// once, parse, validate at the boundary; writers build the bytes in memory and hand them to
// write_file_atomic.
#include "io/io_internal.hpp"

#include <algorithm>
#include <cctype>
#include <cmath>

namespace gsd::io {

namespace {

using CloudReader = PointCloud (*)(const std::string&, std::string_view);
using CloudWriter = std::string (*)(const PointCloud&);
using MeshReader = PolygonMesh (*)(const std::string&, std::string_view);
using MeshWriter = std::string (*)(const PolygonMesh&);

constexpr const char* kCloudFormats = ".ply .xyz .xyzn .txt .pc .obj .npy";
constexpr const char* kMeshFormats = ".obj .ply .off .stl";

[[noreturn]] void unsupported(const std::string& path, const std::string& ext, const char* supported) {
    if (ext.empty())
        throw Error(path, std::string("file name has no extension, so its format is unknown (supported: ") +
                              supported + ")");
    throw Error(path, "unsupported format '" + ext + "' (supported: " + supported + ")");
}

bool is_xyz_like(const std::string& ext) { return ext == ".xyz" || ext == ".xyzn" || ext == ".txt"; }

CloudReader cloud_reader(const std::string& path) {
    const std::string ext = extension(path);
    if (ext == ".ply") return detail::read_ply_cloud;
    if (is_xyz_like(ext)) return detail::read_xyz_cloud;
    if (ext == ".pc") return detail::read_pc_cloud;
    if (ext == ".obj") return detail::read_obj_cloud;
    if (ext == ".npy") return detail::read_npy_cloud;
    unsupported(path, ext, kCloudFormats);
}

CloudWriter cloud_writer(const std::string& path) {
    const std::string ext = extension(path);
    if (ext == ".ply") return detail::ply_cloud_bytes;
    if (is_xyz_like(ext)) return detail::xyz_cloud_bytes;
    if (ext == ".pc") return detail::pc_cloud_bytes;
    if (ext == ".obj") return detail::obj_cloud_bytes;
    if (ext == ".npy") return detail::npy_cloud_bytes;
    unsupported(path, ext, kCloudFormats);
}

MeshReader mesh_reader(const std::string& path) {
    const std::string ext = extension(path);
    if (ext == ".obj") return detail::read_obj_mesh;
    if (ext == ".ply") return detail::read_ply_mesh;
    if (ext == ".off") return detail::read_off_mesh;
    if (ext == ".stl") return detail::read_stl_mesh;
    unsupported(path, ext, kMeshFormats);
}

MeshWriter mesh_writer(const std::string& path) {
    const std::string ext = extension(path);
    if (ext == ".obj") return detail::obj_mesh_bytes;
    if (ext == ".ply") return detail::ply_mesh_bytes;
    if (ext == ".off") return detail::off_mesh_bytes;
    if (ext == ".stl") return detail::stl_mesh_bytes;
    unsupported(path, ext, kMeshFormats);
}

/// What a writer refuses: a cloud its own reader would reject for structural reasons.
void check_writable(const std::string& path, const PointCloud& cloud) {
    if (cloud.points.rows() == 0) throw Error(path, "cannot write an empty point cloud");
    if (cloud.normals.rows() != cloud.points.rows())
        throw Error(path, "cannot write a point cloud whose point and normal counts differ");
    if (!cloud.points.allFinite() || !cloud.normals.allFinite())
        throw Error(path, "cannot write a point cloud with non-finite coordinates or normals");
}

/// What a file of this format needs to carry normals, for the message when it has none.
std::string normals_hint(const std::string& ext) {
    if (ext == ".ply") return "needs nx ny nz";
    if (ext == ".obj" || ext == ".pc") return "needs vn lines";
    if (ext == ".npy") return "needs nx ny nz: shape (N, 6), x y z nx ny nz per row";
    return "needs nx ny nz: 6 numbers per line, x y z nx ny nz";
}

}  // namespace

PointCloud read_point_cloud(const std::string& path) {
    PointCloud cloud = read_cloud_points(path);
    if (cloud.normals.rows() == 0) throw Error(path, "point cloud has no normals (" + normals_hint(extension(path)) + ")");
    return cloud;
}

PointCloud read_cloud_points(const std::string& path) {
    const CloudReader read = cloud_reader(path);
    const std::string bytes = detail::read_whole_file(path);
    PointCloud cloud = read(path, bytes);
    if (cloud.normals.rows() == 0 && cloud.points.rows() > 0) {
        check_coordinates(cloud.points, path, "point");
        return cloud;
    }
    validate(cloud, path);
    normalize_normals(cloud, path);
    return cloud;
}

void write_point_cloud(const std::string& path, const PointCloud& cloud) {
    const CloudWriter bytes_of = cloud_writer(path);
    check_writable(path, cloud);
    write_file_atomic(path, bytes_of(cloud));
}

PolygonMesh read_mesh(const std::string& path) {
    const MeshReader read = mesh_reader(path);
    const std::string bytes = detail::read_whole_file(path);
    PolygonMesh mesh = read(path, bytes);
    validate(mesh, path);
    return mesh;
}

void write_mesh(const std::string& path, const PolygonMesh& mesh) {
    const MeshWriter bytes_of = mesh_writer(path);
    validate(mesh, path);
    write_file_atomic(path, bytes_of(mesh));
}

void write_colored_mesh(const std::string& path, const PolygonMesh& mesh,
                        const std::vector<std::array<std::uint8_t, 3>>& colors, const std::vector<double>& values,
                        const std::string& value_name) {
    if (extension(path) != ".ply") throw Error(path, "colored meshes are written as .ply only");
    validate(mesh, path);
    const auto n = std::size_t(mesh.vertices.rows());
    if (colors.size() != n)
        throw Error(path, "mesh has " + std::to_string(n) + " vertices but " + std::to_string(colors.size()) +
                              " colors were given");
    if (!values.empty() && values.size() != n)
        throw Error(path, "mesh has " + std::to_string(n) + " vertices but " + std::to_string(values.size()) +
                              " values were given");
    // The name goes into the text header: one printable token, not one of the other properties.
    const bool printable = std::all_of(value_name.begin(), value_name.end(),
                                       [](char c) { return std::isgraph(static_cast<unsigned char>(c)); });
    for (const char* taken : {"x", "y", "z", "red", "green", "blue"})
        if (value_name == taken) throw Error(path, "value name '" + value_name + "' is taken by another property");
    if (value_name.empty() || !printable)
        throw Error(path, "value name must be one word of printable characters");
    write_file_atomic(path, detail::ply_colored_mesh_bytes(mesh, colors, values, value_name));
}

bool file_has_faces(const std::string& path) {
    const std::string ext = extension(path);
    if (ext == ".off" || ext == ".stl") {
        detail::require_regular_file(path);
        return true;
    }
    if (ext == ".obj") return detail::obj_has_faces(detail::read_whole_file(path));
    if (ext == ".ply") return detail::ply_has_faces(path, detail::read_whole_file(path));
    if (ext == ".npy" || ext == ".pc" || is_xyz_like(ext)) {
        detail::require_regular_file(path);
        return false;
    }
    unsupported(path, ext, ".ply .obj .off .stl .xyz .xyzn .txt .pc .npy");
}

NpyArray read_npy(const std::string& path) { return detail::parse_npy(path, detail::read_whole_file(path)); }

void write_npy(const std::string& path, const std::vector<std::size_t>& shape, const float* values,
               std::size_t count) {
    write_file_atomic(path, detail::npy_bytes(path, shape, values, count));
}

void write_npy(const std::string& path, const std::vector<std::size_t>& shape, const std::vector<float>& values) {
    write_npy(path, shape, values.data(), values.size());
}

void write_npy(const std::string& path, const std::vector<std::size_t>& shape, const std::vector<std::int32_t>& values) {
    write_file_atomic(path, detail::npy_bytes(path, shape, values.data(), values.size()));
}

Points read_queries(const std::string& path) {
    // Straight from the file's bytes into the queries: a 10⁶-query list is 24 MB of doubles,
    // and an intermediate array would cost a second such allocation and copy.
    Points q;
    std::vector<std::size_t> shape;
    detail::parse_npy_into(path, detail::read_whole_file(path), shape, [&](std::size_t count) -> double* {
        if (shape.size() != 2 || shape[1] != 3)
            throw Error(path, "query list must have shape (M, 3), found " + detail::npy_shape_text(shape));
        if (shape[0] == 0) throw Error(path, "query list is empty (shape (0, 3))");
        q.resize(Eigen::Index(count / 3), 3);
        return q.data();
    });
    const double* v = q.data();
    for (std::size_t i = 0; i < std::size_t(q.size()); ++i)
        if (!std::isfinite(v[i]))
            throw Error(path, "non-finite query coordinate (query " + std::to_string(i / 3) + ")");
        else if (std::abs(v[i]) > kMaxCoordinate)
            throw Error(path, "query coordinate beyond ±1e30 (query " + std::to_string(i / 3) + ")");
    return q;
}

NpyArray read_grid(const std::string& path) {
    NpyArray a = read_npy(path);
    if (a.shape.size() != 3)
        throw Error(path, "grid must be a 3-D array (N, N, N), found shape " + detail::npy_shape_text(a.shape));
    for (std::size_t d : a.shape)
        if (d < 2)
            throw Error(path, "grid needs at least 2 nodes per axis, found shape " + detail::npy_shape_text(a.shape));
    return a;
}

}  // namespace gsd::io
