// halfedges.cpp — see halfedges.hpp.
#include "mesh/halfedges.hpp"

#include "mesh/geometry.hpp"

#include <array>

namespace gsd::mesh {

namespace {
constexpr std::uint32_t kNone = Halfedges::kNone;
}  // namespace

std::uint32_t ccw(const Halfedges& H, std::uint32_t c) {
    const std::uint32_t f = corner_face(c);
    const int k = corner_index(c);
    const std::uint32_t h = H.twin[corner_id(f, (k + 2) % 3)];  // across the incoming halfedge
    return h == kNone ? kNone : h;  // the twin leaves the vertex: its id is the corner there
}

std::uint32_t cw(const Halfedges& H, std::uint32_t c) {
    const std::uint32_t h = H.twin[c];  // across the outgoing halfedge (id 3f+k = corner id)
    if (h == kNone) return kNone;
    return corner_id(corner_face(h), (corner_index(h) + 1) % 3);
}

Halfedges build_halfedges(const Topology& t) {
    const Triangulation& T = t.mesh;
    Halfedges H;
    H.t = &t;
    H.twin.assign(3 * T.face_count(), kNone);
    for (std::size_t e = 0; e < T.edge_count(); ++e) {
        const std::size_t n = t.edge_halfedges.count(e);
        if (n > 2) ++H.nonmanifold_edges;
        if (n != 2) continue;
        const std::uint32_t a = t.edge_halfedges.begin(e)[0], b = t.edge_halfedges.begin(e)[1];
        if (T.aligned[corner_face(a)][std::size_t(corner_index(a))] == T.aligned[corner_face(b)][std::size_t(corner_index(b))]) {
            ++H.misoriented_edges;
            continue;
        }
        H.twin[a] = b;
        H.twin[b] = a;
    }
    if (!H.manifold()) return H;
    H.cot_weight.assign(3 * T.face_count(), 0.0);
    for (std::size_t f = 0; f < T.face_count(); ++f) {
        if (t.face_areas[f] <= 0) continue;
        const std::array<double, 3> l = face_lengths(T, f);
        // Halfedge k runs from corner k to k + 1: the angle across it is at corner k + 2.
        for (int k = 0; k < 3; ++k) H.cot_weight[corner_id(f, k)] = 0.5 * corner_cot(l, (k + 2) % 3, t.face_areas[f]);
    }
    // Fans: from each unvisited corner walk clockwise to the fan's first corner, then collect.
    H.fan_of.assign(3 * T.face_count(), kNone);
    for (std::uint32_t c0 = 0; c0 < 3 * T.face_count(); ++c0) {
        if (H.fan_of[c0] != kNone) continue;
        std::uint32_t start = c0;
        bool closed = false;
        for (std::uint32_t c = cw(H, c0); c != kNone; c = cw(H, c)) {
            if (c == c0) {
                closed = true;
                break;
            }
            start = c;
        }
        if (closed) start = c0;
        const auto fan = std::uint32_t(H.fan_vertex.size());
        for (std::uint32_t c = start; c != kNone && H.fan_of[c] == kNone; c = ccw(H, c)) {
            H.fan_of[c] = fan;
            H.fan_corners.push_back(c);
        }
        H.fan_begin.push_back(std::uint32_t(H.fan_corners.size()));
        H.fan_vertex.push_back(T.faces[corner_face(c0)][std::size_t(corner_index(c0))]);
        H.fan_closed.push_back(closed);
    }
    return H;
}

}  // namespace gsd::mesh
