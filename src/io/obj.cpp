// Wavefront .obj: point clouds (v + vn, paired by order) and polygon meshes (v + f).
//
// Hand-written rather than tinyobjloader 2.0rc10 (libtinyobjloader-dev): probed on small
// files, it accepts "v abc 0 0" as (0,0,0) and "v 0 0" with no error, keeps out-of-range face
// indices with only a warning, silently drops 2-vertex faces, returns success with no data on
// random bytes, and stores float32 coordinates. See docs/io.md.
#include "io/io_internal.hpp"

#include <algorithm>
#include <array>

namespace gsd::io::detail {

namespace {

enum class ObjStatement { vertex, normal, face, ignored, unknown };

/// Statements of the OBJ spec that carry nothing we read (texture coordinates, groups,
/// materials, free-form geometry, lines and points) are ignored; anything else is an error,
/// which also stops a non-OBJ file from reading as an empty one.
ObjStatement classify(std::string_view key) {
    if (key == "v") return ObjStatement::vertex;
    if (key == "vn") return ObjStatement::normal;
    if (key == "f" || key == "fo") return ObjStatement::face;
    static constexpr std::array<std::string_view, 34> kIgnored{
        "vt",    "vp",   "l",     "p",      "g",        "o",          "s",         "usemtl", "mtllib",
        "cstype", "deg", "bmat",  "step",   "curv",     "curv2",      "surf",      "parm",   "trim",
        "hole",  "scrv", "sp",    "end",    "con",      "mg",         "lod",       "usemap", "maplib",
        "shadow_obj", "trace_obj", "ctech", "stech", "bevel", "c_interp", "d_interp"};
    return std::find(kIgnored.begin(), kIgnored.end(), key) != kIgnored.end() ? ObjStatement::ignored
                                                                               : ObjStatement::unknown;
}

[[noreturn]] void unknown_statement(const std::string& path, std::size_t line, std::string_view key) {
    fail(path, at_line(line, "unknown OBJ statement " + quoted(key)));
}

/// "v x y z [w]" or "v x y z r g b" (vertex colors): the first three numbers are the position.
void read_vertex(const std::string& path, std::size_t line, Tokens tokens, std::vector<double>& out) {
    const std::size_t n = tokens.count_left();
    if (n < 3 || n > 7)
        fail(path, at_line(line, "'v' needs 3 numbers (x y z), found " + std::to_string(n) + " values"));
    std::string_view t;
    for (int k = 0; k < 3 && tokens.next(t); ++k) out.push_back(finite_number(t, path, line, "a coordinate"));
    while (tokens.next(t)) finite_number(t, path, line, "a number");  // w or colors: checked, unused
}

void read_normal(const std::string& path, std::size_t line, Tokens tokens, std::vector<double>& out) {
    const std::size_t n = tokens.count_left();
    if (n != 3) fail(path, at_line(line, "'vn' needs 3 numbers, found " + std::to_string(n)));
    std::string_view t;
    while (tokens.next(t)) out.push_back(finite_number(t, path, line, "a normal component"));
}

/// Faces reference vertices that may come later in the file (positive indices), so the range
/// check against the final count happens at the end; the largest index and its line are kept.
struct FaceReader {
    const std::string& path;
    PolygonMesh& mesh;
    std::uint64_t largest = 0;
    std::size_t largest_line = 0;

    /// One corner "i", "i/t", "i//n" or "i/t/n"; negative i counts back from the last vertex.
    std::uint32_t corner(std::size_t line, std::string_view token, std::size_t vertices_so_far) {
        const std::string_view index = token.substr(0, token.find('/'));
        long long i = 0;
        if (!parse_int(index, i)) fail(path, at_line(line, "bad face vertex " + quoted(token)));
        if (i == 0) fail(path, at_line(line, "face vertex index 0 (OBJ indices start at 1)"));
        long long zero_based = i > 0 ? i - 1 : static_cast<long long>(vertices_so_far) + i;
        if (zero_based < 0)
            fail(path, at_line(line, "relative face index " + std::to_string(i) + " points before the first vertex"));
        if (zero_based >= static_cast<long long>(UINT32_MAX))
            fail(path, at_line(line, "face index " + std::to_string(i) + " is too large"));
        if (std::uint64_t(zero_based) >= largest) {
            largest = std::uint64_t(zero_based);
            largest_line = line;
        }
        return std::uint32_t(zero_based);
    }

    void face(std::size_t line, Tokens tokens, std::size_t vertices_so_far) {
        std::size_t n = 0;
        std::string_view t;
        while (tokens.next(t)) {
            mesh.indices.push_back(corner(line, t, vertices_so_far));
            ++n;
        }
        if (n < 3) fail(path, at_line(line, "face has " + std::to_string(n) + " vertices (needs at least 3)"));
        mesh.offsets.push_back(std::uint32_t(mesh.indices.size()));
    }

    void check_range(std::size_t vertex_count) const {
        if (mesh.face_count() > 0 && largest >= vertex_count)
            fail(path, at_line(largest_line, "face vertex index " + std::to_string(largest + 1) +
                                                 " is out of range (the file has " + std::to_string(vertex_count) +
                                                 " vertices)"));
    }
};

}  // namespace

PointCloud read_obj_cloud(const std::string& path, std::string_view bytes) {
    std::vector<double> points, normals;
    LineScanner lines(bytes);
    std::string_view line, key;
    while (lines.next(line)) {
        Tokens tokens(line);
        if (!tokens.next(key)) continue;
        switch (classify(key)) {
            case ObjStatement::vertex: read_vertex(path, lines.line_number(), tokens, points); break;
            case ObjStatement::normal: read_normal(path, lines.line_number(), tokens, normals); break;
            case ObjStatement::face:
            case ObjStatement::ignored: break;
            case ObjStatement::unknown: unknown_statement(path, lines.line_number(), key);
        }
    }
    if (!normals.empty() && points.size() != normals.size())
        fail(path, std::to_string(points.size() / 3) + " 'v' lines but " + std::to_string(normals.size() / 3) +
                       " 'vn' lines (normals pair with vertices by order, so the counts must match)");
    PointCloud c;
    c.points = Eigen::Map<const Points>(points.data(), Eigen::Index(points.size() / 3), 3);
    c.normals = Eigen::Map<const Points>(normals.data(), Eigen::Index(normals.size() / 3), 3);
    return c;
}

PolygonMesh read_obj_mesh(const std::string& path, std::string_view bytes) {
    std::vector<double> vertices;
    PolygonMesh mesh;
    FaceReader faces{path, mesh};
    LineScanner lines(bytes);
    std::string_view line, key;
    while (lines.next(line)) {
        Tokens tokens(line);
        if (!tokens.next(key)) continue;
        switch (classify(key)) {
            case ObjStatement::vertex: read_vertex(path, lines.line_number(), tokens, vertices); break;
            case ObjStatement::face: faces.face(lines.line_number(), tokens, vertices.size() / 3); break;
            case ObjStatement::normal:
            case ObjStatement::ignored: break;
            case ObjStatement::unknown: unknown_statement(path, lines.line_number(), key);
        }
    }
    faces.check_range(vertices.size() / 3);
    mesh.vertices = Eigen::Map<const Points>(vertices.data(), Eigen::Index(vertices.size() / 3), 3);
    return mesh;
}

bool obj_has_faces(std::string_view bytes) {
    LineScanner lines(bytes);
    std::string_view line, key;
    while (lines.next(line)) {
        Tokens tokens(line);
        if (tokens.next(key) && classify(key) == ObjStatement::face) return true;
    }
    return false;
}

std::string obj_cloud_bytes(const PointCloud& cloud) {
    // The .pc layout ("v" then "vn" per point) is valid OBJ and pairs by order.
    return "# point cloud written by gsd: v/vn pairs\n" + pc_cloud_bytes(cloud);
}

std::string obj_mesh_bytes(const PolygonMesh& mesh) {
    std::string out = "# mesh written by gsd\n";
    out.reserve(std::size_t(mesh.vertices.rows()) * 40 + mesh.indices.size() * 8);
    for (Eigen::Index i = 0; i < mesh.vertices.rows(); ++i) {
        out += 'v';
        for (int k = 0; k < 3; ++k) {
            out += ' ';
            append_number(out, mesh.vertices(i, k));
        }
        out += '\n';
    }
    for (std::size_t f = 0; f < mesh.face_count(); ++f) {
        out += 'f';
        for (auto k = mesh.offsets[f]; k < mesh.offsets[f + 1]; ++k) {
            out += ' ';
            out += std::to_string(mesh.indices[k] + 1);
        }
        out += '\n';
    }
    return out;
}

}  // namespace gsd::io::detail
