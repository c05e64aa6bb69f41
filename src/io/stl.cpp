// STL, ascii and binary. STL stores each triangle's corners separately; the reader welds
// corners with exactly equal coordinates into shared vertices (no tolerance: merging nearby
// but distinct points would change the geometry).
#include "io/io_internal.hpp"

#include <Eigen/Geometry>

#include <array>
#include <cmath>
#include <unordered_map>

namespace gsd::io::detail {

namespace {

constexpr std::size_t kHeaderBytes = 84;     // 80-byte comment + uint32 triangle count
constexpr std::size_t kTriangleBytes = 50;   // normal, 3 corners (float32), uint16 attribute

/// Maps exact coordinates to one vertex index each.
class VertexWelder {
public:
    explicit VertexWelder(std::size_t expected) { index_.reserve(expected); }

    std::uint32_t add(double x, double y, double z) {
        const Key key{bits(x), bits(y), bits(z)};
        const auto [it, inserted] = index_.try_emplace(key, std::uint32_t(coords_.size() / 3));
        if (inserted) coords_.insert(coords_.end(), {x, y, z});
        return it->second;
    }

    Points vertices() const {
        return Eigen::Map<const Points>(coords_.data(), Eigen::Index(coords_.size() / 3), 3);
    }

private:
    using Key = std::array<std::uint64_t, 3>;
    struct KeyHash {
        std::size_t operator()(const Key& k) const {
            std::uint64_t h = 0x9e3779b97f4a7c15ull;
            for (std::uint64_t v : k) {
                h ^= v + 0x9e3779b97f4a7c15ull + (h << 6) + (h >> 2);
                h *= 0xff51afd7ed558ccdull;
            }
            return std::size_t(h ^ (h >> 33));
        }
    };
    /// -0.0 and 0.0 are equal coordinates, so they share a key.
    static std::uint64_t bits(double v) { return std::bit_cast<std::uint64_t>(v == 0.0 ? 0.0 : v); }

    std::unordered_map<Key, std::uint32_t, KeyHash> index_;
    std::vector<double> coords_;
};

bool starts_with_solid(std::string_view bytes) {
    bytes = without_byte_order_mark(bytes);  // as LineScanner reads it
    const std::size_t first = bytes.find_first_not_of(" \t\r\n");
    return first != std::string_view::npos && bytes.substr(first, 5) == "solid";
}

std::uint64_t binary_triangle_count(std::string_view bytes) {
    return load<std::uint32_t>(bytes.data() + 80, std::endian::little);
}

bool is_binary_stl(std::string_view bytes) {
    return bytes.size() >= kHeaderBytes &&
           kHeaderBytes + kTriangleBytes * binary_triangle_count(bytes) == bytes.size();
}

PolygonMesh read_binary_stl(std::string_view bytes) {
    const std::uint64_t n = binary_triangle_count(bytes);
    VertexWelder welder(std::size_t(n / 2 + 16));
    PolygonMesh mesh;
    mesh.indices.reserve(std::size_t(n) * 3);
    mesh.offsets.reserve(std::size_t(n) + 1);
    for (std::uint64_t t = 0; t < n; ++t) {
        const char* corner = bytes.data() + kHeaderBytes + t * kTriangleBytes + 12;  // past the normal
        for (int c = 0; c < 3; ++c, corner += 12) {
            const auto x = load<float>(corner, std::endian::little);
            const auto y = load<float>(corner + 4, std::endian::little);
            const auto z = load<float>(corner + 8, std::endian::little);
            mesh.indices.push_back(welder.add(x, y, z));
        }
        mesh.offsets.push_back(std::uint32_t(mesh.indices.size()));
    }
    mesh.vertices = welder.vertices();
    return mesh;
}

PolygonMesh read_ascii_stl(const std::string& path, std::string_view bytes) {
    VertexWelder welder(bytes.size() / 200 + 16);
    PolygonMesh mesh;
    LineScanner lines(bytes);
    std::string_view line, key, t;
    bool seen_solid = false, in_loop = false;
    std::size_t corners = 0;
    while (lines.next(line)) {
        Tokens tokens(line);
        if (!tokens.next(key)) continue;
        const std::size_t ln = lines.line_number();
        if (!seen_solid && key != "solid") fail(path, at_line(ln, "ascii STL must start with 'solid'"));
        if (key == "solid") {
            seen_solid = true;
        } else if (key == "outer") {
            if (in_loop) fail(path, at_line(ln, "'outer loop' inside another loop"));
            in_loop = true;
            corners = 0;
        } else if (key == "vertex") {
            if (!in_loop) fail(path, at_line(ln, "'vertex' outside an 'outer loop'"));
            if (tokens.count_left() != 3) fail(path, at_line(ln, "'vertex' needs 3 numbers"));
            double xyz[3];
            for (double& v : xyz) {
                tokens.next(t);
                v = finite_number(t, path, ln, "a coordinate");
            }
            mesh.indices.push_back(welder.add(xyz[0], xyz[1], xyz[2]));
            ++corners;
        } else if (key == "endloop") {
            if (!in_loop) fail(path, at_line(ln, "'endloop' without 'outer loop'"));
            if (corners < 3) fail(path, at_line(ln, "facet has " + std::to_string(corners) + " vertices (needs 3)"));
            mesh.offsets.push_back(std::uint32_t(mesh.indices.size()));
            in_loop = false;
        } else if (key != "facet" && key != "endfacet" && key != "endsolid") {
            fail(path, at_line(ln, "unexpected " + quoted(key) + " in ascii STL"));
        }
    }
    if (in_loop) fail(path, "ascii STL ends inside a facet (truncated)");
    mesh.vertices = welder.vertices();
    return mesh;
}

}  // namespace

PolygonMesh read_stl_mesh(const std::string& path, std::string_view bytes) {
    // A binary STL's size is exactly 84 + 50·n; that test comes first because binary files
    // may start with "solid" too.
    if (is_binary_stl(bytes)) return read_binary_stl(bytes);
    if (starts_with_solid(bytes)) return read_ascii_stl(path, bytes);
    if (bytes.size() < kHeaderBytes)
        fail(path, "not an STL file (shorter than a binary STL header and not starting with 'solid')");
    const std::uint64_t n = binary_triangle_count(bytes);
    fail(path, "binary STL header says " + std::to_string(n) + " triangles (" +
                   std::to_string(kHeaderBytes + kTriangleBytes * n) + " bytes) but the file has " +
                   std::to_string(bytes.size()) + " bytes (truncated or not an STL file)");
}

std::string stl_mesh_bytes(const PolygonMesh& mesh) {
    std::size_t triangles = 0;
    for (std::size_t f = 0; f < mesh.face_count(); ++f) triangles += mesh.face_size(f) - 2;
    // The 80-byte comment must not start with "solid": some readers take that as ascii.
    std::string out = "binary STL written by gsd";
    out.resize(80, ' ');
    append_le(out, std::uint32_t(triangles));
    out.reserve(kHeaderBytes + triangles * kTriangleBytes);
    auto corner = [&](std::uint32_t v) { return Eigen::Vector3d(mesh.vertices.row(v).transpose()); };
    for_each_triangle(mesh, [&](std::size_t, std::uint32_t i, std::uint32_t j, std::uint32_t k) {
        const Eigen::Vector3d a = corner(i), b = corner(j), c = corner(k);
        Eigen::Vector3d n = (b - a).cross(c - a);
        n = n.norm() > 0 ? Eigen::Vector3d(n.normalized()) : Eigen::Vector3d::Zero();
        for (const Eigen::Vector3d& p : {n, a, b, c})
            for (int d = 0; d < 3; ++d) append_le(out, float(p[d]));
        append_le(out, std::uint16_t(0));
    });
    return out;
}

}  // namespace gsd::io::detail
