// Mesh topology for the surface methods: fan triangulation, the edge numbering of curve files,
// adjacency lists, areas; and gsd::SurfaceMesh on top of it.
#include <gsd/surface.hpp>
#include "core/disjoint_sets.hpp"

#include "mesh/geometry.hpp"
#include "mesh/topology.hpp"

#include <algorithm>
#include <map>
#include <numeric>
#include <unordered_map>

namespace gsd::mesh {

namespace {

/// One side of an input polygon, a → b, in the walk order that numbers edges.
struct Side {
    std::uint32_t a, b;
};

std::vector<Side> polygon_sides(const PolygonMesh& m) {
    std::vector<Side> sides;
    sides.reserve(m.indices.size());
    for (std::size_t f = 0; f < m.face_count(); ++f) {
        const std::uint32_t* v = m.indices.data() + m.offsets[f];
        const std::size_t n = m.face_size(f);
        for (std::size_t k = 0; k < n; ++k) sides.push_back({v[k], v[(k + 1) % n]});
    }
    return sides;
}

/// Numbers edges by first appearance of their vertex pair among the sides, in linear time:
/// sides are bucketed by their smaller vertex, each bucket sorted by (larger vertex, order).
class EdgeNumbering {
public:
    EdgeNumbering(std::size_t vertex_count, const std::vector<Side>& sides) {
        buckets_.offsets.assign(vertex_count + 1, 0);
        for (const Side& s : sides) ++buckets_.offsets[std::min(s.a, s.b) + 1];
        std::partial_sum(buckets_.offsets.begin(), buckets_.offsets.end(), buckets_.offsets.begin());
        buckets_.ids.resize(sides.size());
        std::vector<std::uint32_t> fill(buckets_.offsets.begin(), buckets_.offsets.end() - 1);
        for (std::uint32_t s = 0; s < sides.size(); ++s) buckets_.ids[fill[std::min(sides[s].a, sides[s].b)]++] = s;
        larger_.resize(sides.size());
        for (std::uint32_t s = 0; s < sides.size(); ++s) larger_[s] = std::max(sides[s].a, sides[s].b);
        // Sort each bucket by (larger vertex, side order); a side is "first" if it starts a run.
        std::vector<std::uint32_t> first_of(sides.size());
        for (std::size_t v = 0; v < vertex_count; ++v) {
            auto* b = buckets_.ids.data() + buckets_.offsets[v];
            auto* e = buckets_.ids.data() + buckets_.offsets[v + 1];
            std::sort(b, e, [&](std::uint32_t x, std::uint32_t y) {
                return larger_[x] != larger_[y] ? larger_[x] < larger_[y] : x < y;
            });
            for (auto* p = b; p != e; ++p) first_of[*p] = (p != b && larger_[p[-1]] == larger_[*p]) ? first_of[p[-1]] : *p;
        }
        // Edge ids in order of the first side of each pair.
        side_edge_.resize(sides.size());
        for (std::uint32_t s = 0; s < sides.size(); ++s) {
            if (first_of[s] == s) {
                side_edge_[s] = std::uint32_t(edges_.size());
                edges_.push_back({sides[s].a, sides[s].b});
            } else {
                side_edge_[s] = side_edge_[first_of[s]];
            }
        }
    }

    std::uint32_t edge_of_side(std::size_t s) const { return side_edge_[s]; }
    const std::vector<std::array<std::uint32_t, 2>>& edges() const { return edges_; }

    /// The edge joining a and b among the numbered ones, or UINT32_MAX.
    std::uint32_t find(std::uint32_t a, std::uint32_t b) const {
        const std::uint32_t lo = std::min(a, b), hi = std::max(a, b);
        const auto* first = buckets_.begin(lo);
        const auto* last = buckets_.end(lo);
        const auto* it = std::lower_bound(first, last, hi, [&](std::uint32_t s, std::uint32_t h) { return larger_[s] < h; });
        return (it != last && larger_[*it] == hi) ? side_edge_[*it] : UINT32_MAX;
    }

private:
    Adjacency buckets_;
    std::vector<std::uint32_t> larger_;
    std::vector<std::uint32_t> side_edge_;
    std::vector<std::array<std::uint32_t, 2>> edges_;
};

/// Fan triangles (v0, vk, vk+1) of every polygon, with their halfedges on numbered edges;
/// diagonals get new edges after the file edges.
void triangulate(Topology& t, const EdgeNumbering& numbering) {
    const PolygonMesh& m = t.polygons;
    Triangulation& T = t.mesh;
    T.edges = numbering.edges();
    std::unordered_map<std::uint64_t, std::uint32_t> diagonals;
    auto diagonal = [&](std::uint32_t a, std::uint32_t b) {
        const std::uint32_t found = numbering.find(a, b);
        if (found != UINT32_MAX) return found;
        const std::uint64_t key = (std::uint64_t(std::min(a, b)) << 32) | std::max(a, b);
        auto [it, inserted] = diagonals.try_emplace(key, std::uint32_t(T.edges.size()));
        if (inserted) T.edges.push_back({a, b});
        return it->second;
    };
    std::size_t side = 0;
    for (std::size_t f = 0; f < m.face_count(); ++f) {
        const std::uint32_t* v = m.indices.data() + m.offsets[f];
        const std::size_t n = m.face_size(f);
        for (std::size_t k = 1; k + 1 < n; ++k) {
            const std::array<std::uint32_t, 3> tri{v[0], v[k], v[k + 1]};
            const std::uint32_t e0 = k == 1 ? numbering.edge_of_side(side) : diagonal(v[0], v[k]);
            const std::uint32_t e1 = numbering.edge_of_side(side + k);
            const std::uint32_t e2 = k + 2 == n ? numbering.edge_of_side(side + n - 1) : diagonal(v[k + 1], v[0]);
            T.faces.push_back(tri);
            T.face_edges.push_back({e0, e1, e2});
            std::array<std::uint8_t, 3> al{};
            for (int h = 0; h < 3; ++h) al[std::size_t(h)] = T.edges[T.face_edges.back()[std::size_t(h)]][0] == tri[std::size_t(h)];
            T.aligned.push_back(al);
            t.triangle_face.push_back(std::uint32_t(f));
        }
        side += n;
    }
}

}  // namespace

Adjacency corner_adjacency(std::size_t items, const std::vector<std::array<std::uint32_t, 3>>& per_corner) {
    Adjacency a;
    a.offsets.assign(items + 1, 0);
    for (const auto& c : per_corner)
        for (std::uint32_t x : c) ++a.offsets[x + 1];
    std::partial_sum(a.offsets.begin(), a.offsets.end(), a.offsets.begin());
    a.ids.resize(a.offsets.back());
    std::vector<std::uint32_t> fill(a.offsets.begin(), a.offsets.end() - 1);
    for (std::size_t f = 0; f < per_corner.size(); ++f)
        for (int k = 0; k < 3; ++k) a.ids[fill[per_corner[f][std::size_t(k)]]++] = corner_id(f, k);
    return a;
}

namespace {

void measure(Topology& t) {
    Triangulation& T = t.mesh;
    const Points& x = t.polygons.vertices;
    T.edge_lengths.resize(T.edges.size());
    for (std::size_t e = 0; e < T.edges.size(); ++e)
        T.edge_lengths[e] = (x.row(T.edges[e][0]) - x.row(T.edges[e][1])).norm();
    t.face_areas = face_areas(T);
    t.mean_edge_length = mean_edge_length(T, t.face_areas);
}

}  // namespace

std::uint32_t Topology::find_edge(std::uint32_t a, std::uint32_t b) const {
    for (const std::uint32_t* c = vertex_corners.begin(a); c != vertex_corners.end(a); ++c) {
        const std::uint32_t f = corner_face(*c);
        const int k = corner_index(*c);
        // The two halfedges at this corner: k (a → next) and k+2 (previous → a).
        if (mesh.faces[f][std::size_t((k + 1) % 3)] == b) return mesh.face_edges[f][std::size_t(k)];
        if (mesh.faces[f][std::size_t((k + 2) % 3)] == b) return mesh.face_edges[f][std::size_t((k + 2) % 3)];
    }
    return UINT32_MAX;
}

std::uint32_t Topology::component_of(int kind, std::uint32_t index) const {
    const Adjacency& holders = kind == 0 ? vertex_corners : edge_halfedges;
    if (kind == 2) return face_component[index];
    for (const std::uint32_t* c = holders.begin(index); c != holders.end(index); ++c)
        if (face_component[corner_face(*c)] != UINT32_MAX) return face_component[corner_face(*c)];
    return UINT32_MAX;
}

namespace {

/// Non-degenerate triangles joined through shared edges (union–find), numbered in face order.
std::vector<std::uint32_t> face_components(const Topology& t) {
    const std::size_t F = t.mesh.face_count();
    detail::DisjointSets components(F);
    for (std::size_t e = 0; e < t.mesh.edge_count(); ++e) {
        std::uint32_t first = UINT32_MAX;
        for (const std::uint32_t* h = t.edge_halfedges.begin(e); h != t.edge_halfedges.end(e); ++h) {
            const std::uint32_t f = corner_face(*h);
            if (t.degenerate(f)) continue;
            if (first == UINT32_MAX) first = f;
            else components.join(f, first);
        }
    }
    std::vector<std::uint32_t> label(F, UINT32_MAX), id(F, UINT32_MAX);
    std::uint32_t next = 0;
    for (std::uint32_t f = 0; f < F; ++f) {
        if (t.degenerate(f)) continue;
        std::uint32_t& r = id[components.find(f)];
        if (r == UINT32_MAX) r = next++;
        label[f] = r;
    }
    return label;
}

}  // namespace

Topology build_topology(PolygonMesh mesh) {
    Topology t;
    t.polygons = std::move(mesh);
    const std::size_t n = std::size_t(t.polygons.vertices.rows());
    t.mesh.vertex_count = std::uint32_t(n);
    const std::vector<Side> sides = polygon_sides(t.polygons);
    const EdgeNumbering numbering(n, sides);
    t.file_edge_count = std::uint32_t(numbering.edges().size());
    triangulate(t, numbering);
    t.edge_halfedges = corner_adjacency(t.mesh.edges.size(), t.mesh.face_edges);
    t.vertex_corners = corner_adjacency(n, t.mesh.faces);
    measure(t);
    t.face_component = face_components(t);
    return t;
}

/// Edges with |value| > ½ as 3D polylines along their direction (flipped where negative),
/// chained where one ends where the next starts.
Polylines chain_polylines(const Topology& t, const std::vector<double>& value) {
    const Triangulation& T = t.mesh;
    std::multimap<std::uint32_t, std::pair<std::uint32_t, std::uint32_t>> from;  // tail → (head, edge)
    std::vector<std::uint8_t> used(T.edge_count(), 0);
    std::map<std::uint32_t, int> indegree;
    for (std::size_t e = 0; e < T.edge_count(); ++e) {
        if (std::abs(value[e]) <= 0.5) continue;
        auto [a, b] = T.edges[e];
        if (value[e] < 0) std::swap(a, b);
        from.insert({a, {b, std::uint32_t(e)}});
        ++indegree[b];
    }
    const Points& x = t.polygons.vertices;
    Polylines out;
    auto follow = [&](std::uint32_t v) {
        std::vector<Eigen::Vector3d> line{x.row(v).transpose()};
        for (;;) {
            auto [lo, hi] = from.equal_range(v);
            auto it = lo;
            while (it != hi && used[it->second.second]) ++it;
            if (it == hi) break;
            used[it->second.second] = 1;
            v = it->second.first;
            line.push_back(x.row(v).transpose());
        }
        if (line.size() > 1) out.push_back(std::move(line));
    };
    for (const auto& [v, next] : from)
        if (!indegree.count(v)) follow(v);
    for (const auto& [v, next] : from)
        if (!used[next.second]) follow(v);
    return out;
}

}  // namespace gsd::mesh

namespace gsd {

using mesh::Topology;

SurfaceMesh::SurfaceMesh(PolygonMesh mesh, const std::string& where) {
    validate(mesh, where);
    if (mesh.indices.size() >= std::size_t(UINT32_MAX) / 4)
        throw Error(where, "mesh too large for the surface methods (more than 10⁹ face corners)");
    auto t = std::make_shared<Topology>(mesh::build_topology(std::move(mesh)));
    if (t->mean_edge_length <= 0) throw Error(where, "every triangle of the mesh is degenerate (zero area)");
    topology_ = std::move(t);
}

std::size_t SurfaceMesh::vertex_count() const { return topology_->mesh.vertex_count; }
std::size_t SurfaceMesh::face_count() const { return topology_->polygons.face_count(); }
std::size_t SurfaceMesh::triangle_count() const { return topology_->mesh.faces.size(); }
std::size_t SurfaceMesh::edge_count() const { return topology_->mesh.edges.size(); }
std::size_t SurfaceMesh::file_edge_count() const { return topology_->file_edge_count; }
std::array<std::uint32_t, 2> SurfaceMesh::edge(std::size_t e) const { return topology_->mesh.edges.at(e); }
std::array<std::uint32_t, 3> SurfaceMesh::triangle(std::size_t t) const { return topology_->mesh.faces.at(t); }
std::uint32_t SurfaceMesh::triangle_face(std::size_t t) const { return topology_->triangle_face.at(t); }
const PolygonMesh& SurfaceMesh::polygons() const { return topology_->polygons; }

PolygonMesh SurfaceMesh::triangles() const {
    PolygonMesh m;
    m.vertices = topology_->polygons.vertices;
    m.indices.reserve(3 * triangle_count());
    m.offsets.reserve(triangle_count() + 1);
    for (const auto& f : topology_->mesh.faces) m.add_face(f.data(), 3);
    return m;
}

SurfaceMesh::Summary SurfaceMesh::summary() const {
    const Topology& t = *topology_;
    const mesh::Triangulation& T = t.mesh;
    Summary s;
    for (std::size_t e = 0; e < T.edges.size(); ++e) {
        const std::size_t n = t.edge_halfedges.count(e);
        if (n == 1) ++s.boundary_edges;
        if (n >= 3) ++s.nonmanifold_edges;
        if (n == 2) {
            const std::uint32_t h0 = t.edge_halfedges.begin(e)[0], h1 = t.edge_halfedges.begin(e)[1];
            const bool a0 = T.aligned[mesh::corner_face(h0)][std::size_t(mesh::corner_index(h0))];
            const bool a1 = T.aligned[mesh::corner_face(h1)][std::size_t(mesh::corner_index(h1))];
            if (a0 == a1) ++s.misoriented_edges;
        }
    }
    for (std::size_t f = 0; f < T.faces.size(); ++f) s.degenerate_triangles += t.degenerate(f);
    // Components: triangles joined through shared edges (union–find over edges' halfedges).
    detail::DisjointSets components(T.faces.size());
    for (std::size_t e = 0; e < T.edges.size(); ++e) {
        const std::uint32_t* h = t.edge_halfedges.begin(e);
        for (std::size_t i = 1; i < t.edge_halfedges.count(e); ++i)
            components.join(mesh::corner_face(h[i]), mesh::corner_face(h[0]));
    }
    for (std::uint32_t f = 0; f < T.faces.size(); ++f) s.components += components.find(f) == f;
    std::size_t referenced = 0;
    for (std::size_t v = 0; v < T.vertex_count; ++v) referenced += t.vertex_corners.count(v) > 0;
    s.unreferenced_vertices = T.vertex_count - referenced;
    s.euler_characteristic = (long long)referenced - (long long)T.edges.size() + (long long)T.faces.size();
    s.mean_edge_length = t.mean_edge_length;
    return s;
}

}  // namespace gsd
