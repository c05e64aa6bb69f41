// Face-by-face assembly of the surface operators. The Crouzeix–Raviart basis function of the
// edge opposite corner k is 1 − 2λ_k, so on one face its stiffness is 4× the linear one: between
// the edges meeting at corner m, −2 cot θ_m; on an edge's diagonal, 2 × (the cotangents at its
// two ends). Its mass matrix is diagonal (A/3 per edge: the CR functions are orthogonal on a
// triangle). The connection version rotates each edge's complex value into the face's plane:
// L_jk = S_jk · conj(r_j) · r_k, r the unit direction of the edge in that face.
#include "surface_shm/operators.hpp"
#include "core/disjoint_sets.hpp"

#include "mesh/topology.hpp"

#include <algorithm>
#include <cmath>
#include <numeric>

namespace gsd::surface_shm {

// The mesh module's types and geometry (src/mesh), which these methods are written over.
using namespace mesh;

FaceFrame face_frame(const Triangulation& T, std::size_t f, double area) {
    FaceFrame F;
    F.area = area;
    const auto l = face_lengths(T, f);
    F.p = layout(l);
    for (int k = 0; k < 3; ++k) {
        const Eigen::Vector2d d = F.p[std::size_t((k + 1) % 3)] - F.p[std::size_t(k)];
        const double n = d.norm();
        Complex r = n > 0 ? Complex(d.x() / n, d.y() / n) : Complex(1, 0);
        F.edge_dir[std::size_t(k)] = T.aligned[f][std::size_t(k)] ? r : -r;
        F.cot[std::size_t(k)] = area > 0 ? corner_cot(l, k, area) : 0.0;
    }
    return F;
}

SparseLower<double> cotan_laplacian(const Triangulation& T, const std::vector<double>& areas) {
    SparseLower<double> K(T.vertex_count);
    K.reserve(9 * T.face_count() + T.vertex_count);
    std::vector<double> diagonal(T.vertex_count, 0.0);
    std::vector<std::uint8_t> on_face(T.vertex_count, 0);
    for (std::size_t f = 0; f < T.face_count(); ++f) {
        const FaceFrame F = face_frame(T, f, areas[f]);
        for (int k = 0; k < 3; ++k) {
            // The side opposite corner k joins corners k+1 and k+2, weight ½ cot θ_k.
            const std::uint32_t i = T.faces[f][std::size_t((k + 1) % 3)];
            const std::uint32_t j = T.faces[f][std::size_t((k + 2) % 3)];
            const double w = 0.5 * F.cot[std::size_t(k)];
            diagonal[i] += w;
            diagonal[j] += w;
            if (i != j) K.add(std::max(i, j), std::min(i, j), -w);  // an entry even when w = 0
            else diagonal[i] -= 2 * w;                               // a loop edge: no energy
            if (areas[f] > 0) on_face[i] = on_face[j] = 1;
        }
    }
    for (std::size_t v = 0; v < T.vertex_count; ++v) K.add(v, v, on_face[v] ? diagonal[v] : 1.0);
    return K;
}

StiffnessComponents stiffness_components(const Triangulation& T, const std::vector<double>& areas) {
    detail::DisjointSets components(T.vertex_count);
    std::vector<std::uint8_t> on_face(T.vertex_count, 0);
    for (std::size_t f = 0; f < T.face_count(); ++f) {
        if (areas[f] <= 0) continue;
        const auto& c = T.faces[f];
        for (std::uint32_t v : c) on_face[v] = 1;
        components.join(c[1], c[0]);
        components.join(c[2], c[0]);
    }
    StiffnessComponents s;
    s.component.assign(T.vertex_count, UINT32_MAX);
    std::vector<std::uint32_t> index_of_root(T.vertex_count, UINT32_MAX);
    for (std::uint32_t v = 0; v < T.vertex_count; ++v) {
        if (!on_face[v]) continue;
        std::uint32_t& id = index_of_root[components.find(v)];
        if (id == UINT32_MAX) {
            id = std::uint32_t(s.pins.size());
            s.pins.push_back(v);
        }
        s.component[v] = id;
    }
    return s;
}

std::vector<double> vertex_masses(const Triangulation& T, const std::vector<double>& areas) {
    std::vector<double> m(T.vertex_count, 0.0);
    for (std::size_t f = 0; f < T.face_count(); ++f)
        for (std::uint32_t v : T.faces[f]) m[v] += areas[f] / 3;
    return m;
}

SparseLower<Complex> vector_heat_operator(const Triangulation& T, const std::vector<double>& areas, double t) {
    SparseLower<Complex> A(T.edge_count());
    A.reserve(6 * T.face_count() + T.edge_count());
    std::vector<double> diagonal(T.edge_count(), 0.0);
    std::vector<std::uint8_t> on_face(T.edge_count(), 0);
    for (std::size_t f = 0; f < T.face_count(); ++f) {
        if (areas[f] <= 0) continue;
        const FaceFrame F = face_frame(T, f, areas[f]);
        const auto& e = T.face_edges[f];
        for (int j = 0; j < 3; ++j) {
            // Halfedge j joins corners j and j+1: stiffness 2(cot θ_j + cot θ_{j+1}), mass A/3.
            const double s = 2 * (F.cot[std::size_t(j)] + F.cot[std::size_t((j + 1) % 3)]);
            diagonal[e[std::size_t(j)]] += areas[f] / 3 + t * s;
            on_face[e[std::size_t(j)]] = 1;
            // Halfedges j and j+1 meet at corner j+1: stiffness −2 cot θ_{j+1}.
            const int k = (j + 1) % 3;
            const double s_jk = -2 * F.cot[std::size_t(k)];
            const Complex L_jk = t * s_jk * std::conj(F.edge_dir[std::size_t(j)]) * F.edge_dir[std::size_t(k)];
            const std::uint32_t ej = e[std::size_t(j)], ek = e[std::size_t(k)];
            if (ej > ek) A.add(ej, ek, L_jk);
            else if (ek > ej) A.add(ek, ej, std::conj(L_jk));
            else diagonal[ej] += 2 * L_jk.real();  // two halfedges of one face on one edge
        }
    }
    for (std::size_t e = 0; e < T.edge_count(); ++e) A.add(e, e, on_face[e] ? diagonal[e] : 1.0);
    return A;
}

std::size_t normalized_face_field(const Triangulation& T, const std::vector<double>& areas,
                                  const std::vector<Complex>& X, std::vector<Eigen::Vector2d>& Y) {
    Y.assign(T.face_count(), Eigen::Vector2d::Zero());
    std::size_t vanished = 0;
    for (std::size_t f = 0; f < T.face_count(); ++f) {
        if (areas[f] <= 0) continue;
        const FaceFrame F = face_frame(T, f, areas[f]);
        Complex sum = 0;
        for (int k = 0; k < 3; ++k) sum += F.edge_dir[std::size_t(k)] * X[T.face_edges[f][std::size_t(k)]];
        const double n = std::abs(sum);
        if (n > 0 && std::isfinite(n)) Y[f] = Eigen::Vector2d(sum.real() / n, sum.imag() / n);
        else ++vanished;
    }
    return vanished;
}

std::vector<double> face_field_divergence(const Triangulation& T, const std::vector<double>& areas,
                                          const std::vector<Eigen::Vector2d>& Y) {
    std::vector<double> g(T.vertex_count, 0.0);
    for (std::size_t f = 0; f < T.face_count(); ++f) {
        if (areas[f] <= 0) continue;
        const FaceFrame F = face_frame(T, f, areas[f]);
        for (int i = 0; i < 3; ++i) {
            // A ∇λ_i = ½ J (p_k − p_j), (i, j, k) counter-clockwise, J the quarter turn.
            const Eigen::Vector2d d = F.p[std::size_t((i + 2) % 3)] - F.p[std::size_t((i + 1) % 3)];
            const Eigen::Vector2d Jd(-d.y(), d.x());
            g[T.faces[f][std::size_t(i)]] += 0.5 * Jd.dot(Y[f]);
        }
    }
    return g;
}

}  // namespace gsd::surface_shm
