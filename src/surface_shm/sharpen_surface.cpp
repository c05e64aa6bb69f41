// Distance sharpening on a surface mesh (thesis §4.4, eq. 4.13), the surface twin of the grid's
// (src/shm/sharpen.hpp, which explains the method): a linear program in φ per vertex,
//
//   max Σ_v m_v s_v φ_v   s.t.  |∇φ|_t ≤ 1 on every triangle t,   φ = 0 at the sources (softly),
//
// solved by diagonally preconditioned PDHG with restarts to the average. ∇φ on a triangle is
// constant (φ is linear there); its two components in the triangle's plane are the rows of one
// dual block. On the CPU in double: surfaces are small next to grids.
#include <gsd/surface.hpp>

#include <Eigen/Geometry>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>

namespace gsd {

namespace {

// As the grid's (src/shm/sharpen.cpp): the objective's weight against the constraints, and
// iterations between restarts per edge of the mesh's diameter.
constexpr double kObjectiveWeight = 0.3;
constexpr int kRestartPerEdge = 6;

struct GradientRows {
    std::array<std::uint32_t, 3> v;
    double g[2][3];  // row r, corner k: ∇B_k · e_r
    double sigma;    // the block's dual step
};

struct Entry {
    std::uint32_t item;  // triangle (gradient) or zero-set row
    double w[2];         // the gradient rows' entries (w[0] only for a zero-set row)
};

struct SurfaceProgram {
    std::vector<GradientRows> tris;
    std::vector<std::vector<std::pair<std::uint32_t, double>>> rows;  // zero-set rows: (vertex, weight)
    std::vector<std::uint32_t> first;   // CSR over vertices
    std::vector<Entry> tri_entries;     // (triangle, corner entries of that vertex)
    std::vector<std::uint32_t> row_first;
    std::vector<std::pair<std::uint32_t, double>> row_entries;  // (row, weight)
    std::vector<double> tau, mass;      // per vertex; τ = 0: not on a triangle (left alone)
    double beta = 0, damping = 1, sign_floor = 0;
    int restart = 1;
};

void add_point(const SurfaceMesh& mesh, const SurfacePoint& p, SurfaceProgram& P) {
    std::vector<std::pair<std::uint32_t, double>> row;
    switch (p.kind) {
        case SurfacePoint::Kind::Vertex: row = {{p.index, 1.0}}; break;
        case SurfacePoint::Kind::Edge: {
            const auto e = mesh.edge(p.index);
            row = {{e[0], 1 - p.u}, {e[1], p.u}};
            break;
        }
        case SurfacePoint::Kind::Face: {
            const auto t = mesh.triangle(p.index);
            row = {{t[0], 1 - p.u - p.v}, {t[1], p.u}, {t[2], p.v}};
            break;
        }
    }
    P.rows.push_back(std::move(row));
}

SurfaceProgram build_program(const SurfaceMesh& mesh, const std::vector<double>& phi0, const SurfaceSources& sources,
                             const SurfaceSharpenOptions& options) {
    SurfaceProgram P;
    const Points& x = mesh.polygons().vertices;
    const std::size_t V = mesh.vertex_count();
    double edge_sum = 0;
    std::size_t edges = 0;
    std::vector<double> area(V, 0.0);
    for (std::size_t t = 0; t < mesh.triangle_count(); ++t) {
        const auto c = mesh.triangle(t);
        const Eigen::Vector3d a = x.row(c[0]).transpose(), b = x.row(c[1]).transpose(), d = x.row(c[2]).transpose();
        const Eigen::Vector3d N = (b - a).cross(d - a);
        const double twice_area = N.norm();
        if (!(twice_area > 0) || !std::isfinite(twice_area)) continue;  // degenerate: no gradient, no constraint
        const Eigen::Vector3d n = N / twice_area, e1 = (b - a).normalized(), e2 = n.cross(e1);
        const Eigen::Vector3d p[3] = {a, b, d};
        GradientRows g{c, {}, 0};
        double row_sum[2] = {0, 0};
        for (int k = 0; k < 3; ++k) {
            const Eigen::Vector3d grad = n.cross(p[(k + 2) % 3] - p[(k + 1) % 3]) / twice_area;  // ∇B_k
            g.g[0][k] = grad.dot(e1), g.g[1][k] = grad.dot(e2);
            row_sum[0] += std::abs(g.g[0][k]), row_sum[1] += std::abs(g.g[1][k]);
            area[c[std::size_t(k)]] += twice_area / 6;
            edge_sum += (p[(k + 1) % 3] - p[k]).norm();
        }
        edges += 3;
        g.sigma = 1 / std::max(row_sum[0], row_sum[1]);
        P.tris.push_back(g);
    }
    if (P.tris.empty()) throw Error("sharpen", "the mesh has no triangle with area");
    const double h = edge_sum / double(edges);
    for (const SurfaceCurve& curve : sources.curves)
        for (const SurfacePoint& node : curve.nodes) add_point(mesh, node, P);
    for (const SurfacePoint& point : sources.points) add_point(mesh, point, P);
    // Rows are scaled by β = 1/h, so that they speak in slopes like the gradient rows; their
    // weights sum to 1, so their dual step σ_q = 1/β and σ_q·β = 1.
    P.beta = 1 / h;
    P.damping = options.zero_set_weight > 0 ? 1 / (1 + h / options.zero_set_weight) : 1.0;
    P.sign_floor = options.keep_sign ? 1e-4 * h : 0.0;
    const Box box = bounding_box(x);
    P.restart = std::max(1, int(std::ceil(kRestartPerEdge * box.diagonal() / h)));

    // Columns: per vertex, the triangles it is a corner of and the rows it appears in.
    std::vector<std::uint32_t> count(V + 1, 0), row_count(V + 1, 0);
    for (const GradientRows& g : P.tris)
        for (std::uint32_t v : g.v) count[v + 1]++;
    for (const auto& row : P.rows)
        for (const auto& [v, w] : row) row_count[v + 1]++;
    for (std::size_t v = 0; v < V; ++v) count[v + 1] += count[v], row_count[v + 1] += row_count[v];
    P.first = count;
    P.row_first = row_count;
    P.tri_entries.resize(count.back());
    P.row_entries.resize(row_count.back());
    std::vector<double> column(V, 0.0);
    for (std::size_t t = 0; t < P.tris.size(); ++t)
        for (int k = 0; k < 3; ++k) {
            const std::uint32_t v = P.tris[t].v[std::size_t(k)];
            P.tri_entries[count[v]++] = {std::uint32_t(t), {P.tris[t].g[0][k], P.tris[t].g[1][k]}};
            column[v] += std::abs(P.tris[t].g[0][k]) + std::abs(P.tris[t].g[1][k]);
        }
    for (std::size_t r = 0; r < P.rows.size(); ++r)
        for (const auto& [v, w] : P.rows[r]) {
            P.row_entries[row_count[v]++] = {std::uint32_t(r), w};
            column[v] += P.beta * std::abs(w);
        }
    double mean_area = 0;
    std::size_t on_triangles = 0;
    for (std::size_t v = 0; v < V; ++v)
        if (area[v] > 0) mean_area += area[v], ++on_triangles;
    mean_area /= double(on_triangles);
    P.tau.assign(V, 0.0);
    P.mass.assign(V, 0.0);
    for (std::size_t v = 0; v < V; ++v) {
        if (!(area[v] > 0)) continue;
        if (!std::isfinite(phi0[v]))
            throw Error("sharpen", "φ₀ is not finite at vertex " + std::to_string(v) + ", a corner of a triangle");
        P.tau[v] = 1 / column[v];
        const double s = phi0[v] > 0 ? 1.0 : phi0[v] < 0 ? -1.0 : 0.0;
        P.mass[v] = kObjectiveWeight * s * area[v] / mean_area;
    }
    return P;
}

struct SurfaceState {
    std::vector<double> phi, phi_bar, p, q, phi_sum, p_sum, q_sum;
    int summed = 0;
};

void iterate(const SurfaceProgram& P, SurfaceState& S) {
    const auto T = std::ptrdiff_t(P.tris.size()), R = std::ptrdiff_t(P.rows.size()), V = std::ptrdiff_t(S.phi.size());
#pragma omp parallel for schedule(static)
    for (std::ptrdiff_t tt = 0; tt < T; ++tt) {
        const auto t = std::size_t(tt);
        const GradientRows& g = P.tris[t];
        double v[2];
        for (int r = 0; r < 2; ++r) {
            double d = 0;
            for (int k = 0; k < 3; ++k) d += g.g[r][k] * S.phi_bar[g.v[std::size_t(k)]];
            v[r] = S.p[2 * t + std::size_t(r)] + g.sigma * d;
        }
        const double len = std::hypot(v[0], v[1]);
        const double keep = len > g.sigma ? 1 - g.sigma / len : 0.0;
        for (int r = 0; r < 2; ++r) S.p[2 * t + std::size_t(r)] = v[r] * keep, S.p_sum[2 * t + std::size_t(r)] += v[r] * keep;
    }
    for (std::ptrdiff_t rr = 0; rr < R; ++rr) {
        const auto r = std::size_t(rr);
        double z = 0;
        for (const auto& [v, w] : P.rows[r]) z += w * S.phi_bar[v];
        S.q[r] = (S.q[r] + z) * P.damping;
        S.q_sum[r] += S.q[r];
    }
#pragma omp parallel for schedule(static)
    for (std::ptrdiff_t vv = 0; vv < V; ++vv) {
        const auto v = std::size_t(vv);
        if (P.tau[v] == 0) continue;
        double kty = 0;
        for (std::uint32_t e = P.first[v]; e < P.first[v + 1]; ++e) {
            const Entry& en = P.tri_entries[e];
            kty += en.w[0] * S.p[2 * en.item] + en.w[1] * S.p[2 * en.item + 1];
        }
        for (std::uint32_t e = P.row_first[v]; e < P.row_first[v + 1]; ++e)
            kty += P.beta * P.row_entries[e].second * S.q[P.row_entries[e].first];
        const double old = S.phi[v], m = P.mass[v];
        double x = old - P.tau[v] * (kty - m);
        if (P.sign_floor > 0) x = m > 0 ? std::max(x, P.sign_floor) : m < 0 ? std::min(x, -P.sign_floor) : x;
        S.phi_bar[v] = 2 * x - old;
        S.phi[v] = x;
        S.phi_sum[v] += x;
    }
}

void restart(SurfaceState& S) {
    const double inv = 1.0 / S.summed;
    for (auto [x, sum] : {std::pair{&S.phi, &S.phi_sum}, std::pair{&S.p, &S.p_sum}, std::pair{&S.q, &S.q_sum}})
        for (std::size_t i = 0; i < x->size(); ++i) (*x)[i] = (*sum)[i] * inv, (*sum)[i] = 0;
    S.phi_bar = S.phi;
    S.summed = 0;
}

}  // namespace

SurfaceSharpenResult sharpen_distance(const SurfaceMesh& mesh, const std::vector<double>& phi0, const SurfaceSources& sources,
                                      const SurfaceSharpenOptions& options, const ProgressFn& progress) {
    const auto t0 = std::chrono::steady_clock::now();
    if (phi0.size() != mesh.vertex_count())
        throw Error("sharpen", "φ₀ has " + std::to_string(phi0.size()) + " values for a mesh of " +
                                   std::to_string(mesh.vertex_count()) + " vertices");
    if (options.iterations < 0) throw Error("SurfaceSharpenOptions::iterations", "iterations must be ≥ 0 (0: automatic)");
    if (!(options.zero_set_weight >= 0) || !std::isfinite(options.zero_set_weight))
        throw Error("SurfaceSharpenOptions::zero_set_weight", "the zero-set weight must be finite and ≥ 0 (0: exact)");
    if (sources.empty()) throw Error("sharpen", "no curves or points to sharpen against");
    validate(sources, mesh, "sharpen");

    const SurfaceProgram P = build_program(mesh, phi0, sources, options);
    const int iterations = options.iterations > 0 ? options.iterations : 4 * P.restart;
    SurfaceState S;
    S.phi = phi0;
    for (std::size_t v = 0; v < S.phi.size(); ++v)
        if (P.tau[v] == 0 && !std::isfinite(S.phi[v])) S.phi[v] = 0;  // kept out of the sums; NaN again below
    S.phi_bar = S.phi;
    S.p.assign(2 * P.tris.size(), 0.0);
    S.q.assign(P.rows.size(), 0.0);
    S.phi_sum.assign(S.phi.size(), 0.0);
    S.p_sum.assign(S.p.size(), 0.0);
    S.q_sum.assign(S.q.size(), 0.0);
    for (int it = 0; it < iterations; ++it) {
        iterate(P, S);
        if (++S.summed == P.restart) restart(S);
        if (progress && (it % 64 == 63 || it + 1 == iterations)) progress("sharpen", double(it + 1) / iterations);
    }

    SurfaceSharpenResult out;
    out.iterations = iterations;
    out.zero_set_rows = P.rows.size();
    for (std::size_t v = 0; v < S.phi.size(); ++v) {
        if (P.tau[v] == 0) {
            S.phi[v] = phi0[v];  // on no triangle: untouched (NaN where the solve left NaN)
            continue;
        }
        out.sign_changes += (phi0[v] < 0) != (S.phi[v] < 0);
    }
    for (const GradientRows& g : P.tris) {
        double d[2] = {0, 0};
        for (int r = 0; r < 2; ++r)
            for (int k = 0; k < 3; ++k) d[r] += g.g[r][k] * S.phi[g.v[std::size_t(k)]];
        out.max_slope = std::max(out.max_slope, std::hypot(d[0], d[1]));
    }
    out.phi = std::move(S.phi);
    out.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    return out;
}

SurfaceSharpenResult SignedHeatSurface::sharpen(const std::vector<double>& phi, const SurfaceSources& sources,
                                               const SurfaceSharpenOptions& options, const ProgressFn& progress) const {
    return sharpen_distance(mesh(), phi, sources, options, progress);
}

}  // namespace gsd
