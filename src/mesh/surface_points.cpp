// Points and curves on a SurfaceMesh: reading them from files (checked against the mesh, errors
// naming the file and line), validation, positions; and the error measures of thesis §4.5.
#include <gsd/io.hpp>
#include <gsd/surface.hpp>

#include "mesh/topology.hpp"

#include <cmath>
#include <cstdio>
#include <string>

namespace gsd {

namespace {

std::string at_line(std::size_t line, const std::string& what) {
    return line ? "line " + std::to_string(line) + ": " + what : what;
}

/// A raw record → a point on the mesh, or an error naming the record's line.
SurfacePoint to_point(const io::CurveFile::Point& p, const SurfaceMesh& mesh, const std::string& path) {
    // Numbers as the file wrote them: from 1 unless it said `#offset 0`.
    auto out_of_range = [&](const char* what, const char* plural, std::size_t count) {
        return Error(path, at_line(p.line, std::string(what) + " index " + std::to_string(p.index + p.base) +
                                               " is out of range (the mesh has " + std::to_string(count) + " " +
                                               (count == 1 ? what : plural) + ", numbered from " +
                                               std::to_string(p.base) + " here)"));
    };
    switch (p.kind) {
        case 'v':
            if (p.index >= mesh.vertex_count()) throw out_of_range("vertex", "vertices", mesh.vertex_count());
            return SurfacePoint::at_vertex(std::uint32_t(p.index));
        case 'e':
            if (p.index >= mesh.file_edge_count()) throw out_of_range("edge", "edges", mesh.file_edge_count());
            return SurfacePoint::on_edge(std::uint32_t(p.index), p.a);
        case 'f':
            if (p.index >= mesh.triangle_count()) throw out_of_range("triangle", "triangles", mesh.triangle_count());
            return SurfacePoint::in_triangle(std::uint32_t(p.index), p.a, p.b);
        default: throw Error(path, at_line(p.line, "unknown point kind"));
    }
}

/// The line (in the file) a point record came from, kept so that validation errors found
/// after reading still name it.
void check_on_face(const SurfacePoint& p, const SurfaceMesh& mesh, const std::string& path, std::size_t line) {
    if (p.kind == SurfacePoint::Kind::Vertex && mesh.topology().vertex_corners.count(p.index) == 0)
        throw Error(path, at_line(line, "vertex " + std::to_string(p.index) + " is on no face of the mesh"));
}

}  // namespace

SurfaceSources read_surface_curves(const std::string& path, const SurfaceMesh& mesh) {
    const io::CurveFile file = io::read_curve_file(path);
    if (file.lines.empty()) throw Error(path, "no curves (no `l` lines) in the file");
    std::vector<SurfacePoint> points;
    points.reserve(file.points.size());
    for (const auto& p : file.points) points.push_back(to_point(p, mesh, path));
    SurfaceSources s;
    const mesh::Topology& t = mesh.topology();
    for (const auto& line : file.lines) {
        SurfaceCurve c;
        std::uint32_t previous = UINT32_MAX;
        std::size_t previous_line = 0;
        for (std::uint32_t i : line.points) {
            check_on_face(points[i], mesh, path, file.points[i].line);
            // Consecutive nodes must be joined by some path of triangles (the piece between
            // them follows the shortest one): on different pieces of the mesh they cannot be.
            const std::uint32_t component = t.component_of(int(points[i].kind), points[i].index);
            if (!c.nodes.empty() && component != UINT32_MAX && previous != UINT32_MAX && component != previous)
                throw Error(path, at_line(line.line, "the segment from the point of line " +
                                                         std::to_string(previous_line) + " to the point of line " +
                                                         std::to_string(file.points[i].line) +
                                                         " joins separate pieces of the mesh: no path connects them"));
            if (component != UINT32_MAX) {
                previous = component;
                previous_line = file.points[i].line;
            }
            c.nodes.push_back(points[i]);
        }
        s.curves.push_back(std::move(c));
    }
    return s;
}

std::vector<SurfacePoint> read_surface_points(const std::string& path, const SurfaceMesh& mesh) {
    const io::CurveFile file = io::read_curve_file(path);
    if (!file.lines.empty() && io::extension(path) != ".obj")
        throw Error(path, at_line(file.lines.front().line, "a points file has no `l` lines (give curves with --curves)"));
    std::vector<SurfacePoint> points;
    for (const auto& p : file.points) {
        points.push_back(to_point(p, mesh, path));
        check_on_face(points.back(), mesh, path, p.line);
    }
    return points;
}

void write_surface_curves(const std::string& path, const SurfaceSources& sources) {
    std::string out = "# curves on a surface written by gsd: v vertex, e edge t, f triangle u v; l joins records\n#offset 0\n";
    char buf[96];
    auto record = [&](const SurfacePoint& p) {
        switch (p.kind) {
            case SurfacePoint::Kind::Vertex: std::snprintf(buf, sizeof(buf), "v %u\n", p.index); break;
            case SurfacePoint::Kind::Edge: std::snprintf(buf, sizeof(buf), "e %u %.17g\n", p.index, p.u); break;
            case SurfacePoint::Kind::Face: std::snprintf(buf, sizeof(buf), "f %u %.17g %.17g\n", p.index, p.u, p.v); break;
        }
        out += buf;
    };
    std::size_t next = 0;
    for (const SurfaceCurve& c : sources.curves) {
        std::string line = "l";
        for (const SurfacePoint& p : c.nodes) {
            record(p);
            line.append(" ").append(std::to_string(next++));
        }
        out.append(line).append("\n");
    }
    for (const SurfacePoint& p : sources.points) record(p);
    io::write_file_atomic(path, out);
}

void validate(const SurfaceSources& sources, const SurfaceMesh& mesh, const std::string& where) {
    auto check = [&](const SurfacePoint& p, const std::string& what) {
        auto fail = [&](const std::string& why) { throw Error(where, what + ": " + why); };
        switch (p.kind) {
            case SurfacePoint::Kind::Vertex:
                if (p.index >= mesh.vertex_count()) fail("vertex " + std::to_string(p.index) + " out of range");
                if (mesh.topology().vertex_corners.count(p.index) == 0)
                    fail("vertex " + std::to_string(p.index) + " is on no face");
                break;
            case SurfacePoint::Kind::Edge:
                if (p.index >= mesh.edge_count()) fail("edge " + std::to_string(p.index) + " out of range");
                if (!(p.u >= 0 && p.u <= 1)) fail("edge parameter t = " + std::to_string(p.u) + " is not in [0, 1]");
                break;
            case SurfacePoint::Kind::Face:
                if (p.index >= mesh.triangle_count()) fail("triangle " + std::to_string(p.index) + " out of range");
                if (!(p.u >= -1e-9 && p.v >= -1e-9 && p.u + p.v <= 1 + 1e-9))
                    fail("barycentric weights (" + std::to_string(p.u) + ", " + std::to_string(p.v) +
                         ") are not inside the triangle");
                break;
            default: fail("unknown point kind");
        }
    };
    for (std::size_t c = 0; c < sources.curves.size(); ++c) {
        const SurfaceCurve& curve = sources.curves[c];
        const std::string name = "curve " + std::to_string(c + 1);
        if (curve.nodes.size() < 2) throw Error(where, name + " has fewer than 2 nodes");
        for (std::size_t i = 0; i < curve.nodes.size(); ++i) check(curve.nodes[i], name + ", node " + std::to_string(i + 1));
    }
    for (std::size_t i = 0; i < sources.points.size(); ++i) check(sources.points[i], "point " + std::to_string(i + 1));
}

Eigen::Vector3d position(const SurfaceMesh& mesh, const SurfacePoint& p) {
    const Points& x = mesh.polygons().vertices;
    switch (p.kind) {
        case SurfacePoint::Kind::Vertex: return x.row(p.index).transpose();
        case SurfacePoint::Kind::Edge: {
            const auto e = mesh.edge(p.index);
            return (1 - p.u) * x.row(e[0]).transpose() + p.u * x.row(e[1]).transpose();
        }
        case SurfacePoint::Kind::Face: {
            const auto t = mesh.triangle(p.index);
            return (1 - p.u - p.v) * x.row(t[0]).transpose() + p.u * x.row(t[1]).transpose() +
                   p.v * x.row(t[2]).transpose();
        }
    }
    return Eigen::Vector3d::Zero();
}

}  // namespace gsd
