// SumTree (sum_tree.hpp): the tree's build and moments, then its walks — fast winding numbers
// (the packet walk itself is in winding_walk.inl), the nearest element, and SHM step 1's
// screened sum with its element refinement (wide faces clipped, needles bisected).
// Long (~950 lines) because every walk reads the tree's private records (Hot, the expansions)
// and shares its refinement helpers; splitting it would expose those records to other files.
#include "sums/sum_tree.hpp"

#include "core/solid_angle.hpp"

#include "core/clip.hpp"

#include "spatial/box_tree.hpp"

#include <Eigen/Geometry>

#include <algorithm>
#include <cmath>
#include <limits>
#include <type_traits>

#if defined(__x86_64__) && defined(__GNUC__)
#include <immintrin.h>
#endif

namespace gsd::sums {

namespace {

using Vec3 = Eigen::Vector3d;

constexpr double kFourPi = 4 * M_PI;
constexpr int kStack = 64;
// Elements per leaf: small, so that clusters of a few elements get their own (cheap)
// expansion instead of exact per-element sums.
constexpr std::uint32_t kLeafSize = 2;

Vec3 vec(const double* p) { return {p[0], p[1], p[2]}; }

/// Covariance of the uniform density on a triangle: (1/12) Σ_k (p_k − g)(p_k − g)ᵀ, as
/// (xx yy zz xy xz yz).
void triangle_covariance(const double* p, double (&cov)[6]) {
    // Scalar on purpose: SHM step 1 calls this for every accepted needle piece, and the Eigen
    // outer-product form cost two thirds of a run on a mesh with one stray vertex.
    double d[3][3];
    for (int a = 0; a < 3; ++a) {
        const double g = (p[a] + p[3 + a] + p[6 + a]) / 3;
        for (int q = 0; q < 3; ++q) d[q][a] = p[3 * q + a] - g;
    }
    const auto s = [&](int u, int w) { return (d[0][u] * d[0][w] + d[1][u] * d[1][w] + d[2][u] * d[2][w]) / 12; };
    cov[0] = s(0, 0); cov[1] = s(1, 1); cov[2] = s(2, 2);
    cov[3] = s(0, 1); cov[4] = s(0, 2); cov[5] = s(1, 2);
}

/// uᵀ S u and tr S for a symmetric S stored as (xx yy zz xy xz yz).
double quad(const double* s, const Vec3& u) {
    return s[0] * u[0] * u[0] + s[1] * u[1] * u[1] + s[2] * u[2] * u[2] +
           2 * (s[3] * u[0] * u[1] + s[4] * u[0] * u[2] + s[5] * u[1] * u[2]);
}
double trace(const double* s) { return s[0] + s[1] + s[2]; }

#if defined(__GNUC__)
#define GSD_ALWAYS_INLINE inline __attribute__((always_inline))
#else
#define GSD_ALWAYS_INLINE inline
#endif

// SHM step 1's walk and element sums compiled twice, for any x86-64 and for x86-64-v3 (AVX2,
// FMA), the copy chosen once at load time (an ifunc): 1.12–1.14× on step 1 on the 2-core Zen 4
// (a 2·10⁵-point scan at depth 9). gcc only: the clang builds are the sanitizers' and fuzzers'.
// Needs an ELF target with glibc's ifuncs and gcc ≥ 11 (arch=x86-64-v3); anywhere else one copy.
// The v3 copy fuses multiply-adds, so its sums may differ from the other's in the last bits.
#if defined(__x86_64__) && defined(__GNUC__) && !defined(__clang__) && __GNUC__ >= 11 && defined(__ELF__) && \
    defined(__GLIBC__) && !defined(__SANITIZE_ADDRESS__)
#define GSD_CLONES_V3 __attribute__((target_clones("arch=x86-64-v3", "default")))
#else
#define GSD_CLONES_V3
#endif

/// Second-order expansion of Σ v·∇Φ(x − y), Φ = 1/(4πr), about c, d = x − c, ir = 1/|d|. With
/// radial derivatives f1..f3 of Φ: ∂_aΦ = f1 u_a, ∂_aiΦ = A u_a u_i + B δ_ai,
/// ∂_aijΦ = C u_a u_i u_j + D (u_a δ_ij + u_i δ_aj + u_j δ_ai), so
/// w = f1 M0·u − (A uᵀS1u + B tr S1) + ½ (C T3(u) + D p·u). With k = 1/4π, f1 = −k/r²,
/// A = 3k/r³, B = −k/r³, C = −15k/r⁴ and D = 3k/r⁴, and u = d/r, that is
///   w = k/r³ · [tr S1 − M0·d + (1.5 p·d − 3 dᵀS1d)/r² − 7.5 T3(d)/r⁴],
/// a polynomial in d whose coefficients winding_node() scales once per node (fewer operations
/// per query than the form in u). Scalar code that the packet walk runs on every lane at once.
template <class Real>
GSD_ALWAYS_INLINE Real winding_expansion(const SumTree::WindingNodeT<Real>& n, Real dx, Real dy, Real dz, Real ir) {
    const Real ir2 = ir * ir;
    const Real xx = dx * dx, yy = dy * dy, zz = dz * dz;
    const Real* s = n.s1;
    const Real* t = n.t3;
    const Real linear = n.k0 + n.m0[0] * dx + n.m0[1] * dy + n.m0[2] * dz;
    const Real second = n.p[0] * dx + n.p[1] * dy + n.p[2] * dz + s[0] * xx + s[1] * yy + s[2] * zz +
                          dx * (s[3] * dy + s[4] * dz) + s[5] * dy * dz;
    const Real third = dx * (t[0] * xx + t[5] * yy + t[7] * zz + t[9] * dy * dz) + dy * (t[1] * yy + t[3] * xx + t[8] * zz) +
                         dz * (t[2] * zz + t[4] * xx + t[6] * yy);
    return ir * ir2 * (linear + ir2 * (second + ir2 * third));
}

/// sums::triangle_winding for one lane (corners p: a, b, c), with atan2_lanes.
GSD_ALWAYS_INLINE double triangle_winding_lane(double x, double y, double z, const double* p) {
    const double ax = p[0] - x, ay = p[1] - y, az = p[2] - z;
    const double bx = p[3] - x, by = p[4] - y, bz = p[5] - z;
    const double cx = p[6] - x, cy = p[7] - y, cz = p[8] - z;
    const double la = std::sqrt(ax * ax + ay * ay + az * az), lb = std::sqrt(bx * bx + by * by + bz * bz),
                 lc = std::sqrt(cx * cx + cy * cy + cz * cz);
    const double num = ax * (by * cz - bz * cy) + ay * (bz * cx - bx * cz) + az * (bx * cy - by * cx);
    const double den = la * lb * lc + (ax * bx + ay * by + az * bz) * lc + (bx * cx + by * cy + bz * cz) * la +
                       (cx * ax + cy * ay + cz * az) * lb;
    return sums::atan2_lanes(num, den) / (2 * M_PI);
}

/// A point element's dipole v·(y − x)/(4π|y − x|³) for one lane; nothing at the point itself.
GSD_ALWAYS_INLINE double point_winding_lane(double x, double y, double z, const double* p, const double* v) {
    const double dx = p[0] - x, dy = p[1] - y, dz = p[2] - z, r2 = dx * dx + dy * dy + dz * dz;
    const double r2s = std::max(r2, DBL_MIN);  // r2 = 0: the numerator is 0 too
    return (v[0] * dx + v[1] * dy + v[2] * dz) / (kFourPi * r2s * std::sqrt(r2s));
}

/// The bit mask of the lanes l with d[l] > r. Written as a sum of powers of two, a `simd`
/// reduction (compare, blend, add), because compilers build the obvious loop one lane at a time
/// (an extract, a shift and an or per lane). The AVX2 walk uses lanes_greater_avx2 instead.
template <class Real>
GSD_ALWAYS_INLINE std::uint32_t lanes_greater(const Real* d, Real r) {
    constexpr int L = SumTree::kLanes;
    alignas(64) static constexpr Real bit[8] = {1, 2, 4, 8, 16, 32, 64, 128};
    static_assert(L <= 8, "one bit per lane");
    Real sum = 0;
#pragma omp simd reduction(+ : sum)
    for (int l = 0; l < L; ++l) sum += d[l] > r ? bit[l] : Real(0);
    return std::uint32_t(sum);
}

/// The symmetric reduction of a node's moments, scaled for winding_expansion.
/// Squared distance from lane l of a packet's queries (q[axis][lane]) to a node's box; 0 inside.
template <int L>
GSD_ALWAYS_INLINE double box_distance2(const SumTree::Hot& h, const double (&q)[3][L], int l) {
    double s = 0;
    for (int a = 0; a < 3; ++a) {
        const double d = std::max(std::max(h.lo[a] - q[a][l], q[a][l] - h.hi[a]), 0.0);
        s += d * d;
    }
    return s;
}

SumTree::WindingNodeT<double> winding_node(const SumTree::Node& n) {
    constexpr double k = 1 / kFourPi;
    SumTree::WindingNodeT<double> w;
    const double* m1 = n.m1;  // m1[3a + i]
    const double s1[6] = {m1[0], m1[4], m1[8], 0.5 * (m1[1] + m1[3]), 0.5 * (m1[2] + m1[6]), 0.5 * (m1[5] + m1[7])};
    w.k0 = k * (s1[0] + s1[1] + s1[2]);
    for (int a = 0; a < 3; ++a) w.m0[a] = -k * n.m0[a];
    // −3k dᵀS1d: diagonal, then the off-diagonal terms twice.
    for (int b = 0; b < 6; ++b) w.s1[b] = -3 * k * s1[b] * (b < 3 ? 1 : 2);
    // M2_a[i][j] = m2[6a + (xx yy zz xy xz yz)].
    auto M = [&](int a, int i, int j) {
        static constexpr int idx[3][3] = {{0, 3, 4}, {3, 1, 5}, {4, 5, 2}};
        return n.m2[6 * a + idx[i][j]];
    };
    enum { X, Y, Z };
    double t3[10];
    t3[0] = M(X, X, X);
    t3[1] = M(Y, Y, Y);
    t3[2] = M(Z, Z, Z);
    t3[3] = M(Y, X, X) + 2 * M(X, X, Y);  // d_x² d_y
    t3[4] = M(Z, X, X) + 2 * M(X, X, Z);  // d_x² d_z
    t3[5] = M(X, Y, Y) + 2 * M(Y, X, Y);  // d_y² d_x
    t3[6] = M(Z, Y, Y) + 2 * M(Y, Y, Z);  // d_y² d_z
    t3[7] = M(X, Z, Z) + 2 * M(Z, X, Z);  // d_z² d_x
    t3[8] = M(Y, Z, Z) + 2 * M(Z, Y, Z);  // d_z² d_y
    t3[9] = 2 * (M(X, Y, Z) + M(Y, X, Z) + M(Z, X, Y));
    for (int b = 0; b < 10; ++b) w.t3[b] = -7.5 * k * t3[b];
    for (int j = 0; j < 3; ++j)
        w.p[j] = 1.5 * k * ((M(j, X, X) + M(j, Y, Y) + M(j, Z, Z)) + 2 * (M(X, X, j) + M(Y, Y, j) + M(Z, Z, j)));
    return w;
}

/// The node in the winding walk's coordinates, (x − origin)·scale: moments of order k carry
/// the vector area (scale²) and k lengths.
SumTree::Node normalized(const SumTree::Node& n, const double* origin, double scale) {
    SumTree::Node m = n;
    for (int a = 0; a < 3; ++a) m.c[a] = (n.c[a] - origin[a]) * scale;
    m.rho = n.rho * scale;
    m.area = n.area * scale * scale;
    for (double& v : m.m0) v *= scale * scale;
    for (double& v : m.m1) v *= scale * scale * scale;
    for (double& v : m.m2) v *= scale * scale * scale * scale;
    return m;
}

/// A node's acceptance record (its center, ρ and q), from the node in the walk's coordinates.
SumTree::WindingTestT<double> winding_test(const SumTree::Node& nd) {
    return {{nd.c[0], nd.c[1], nd.c[2]}, nd.rho, std::pow(nd.area * nd.rho * nd.rho * nd.rho / M_PI, 0.2)};
}

template <class Out, class In, std::size_t N>
void narrow(Out (&out)[N], const In (&in)[N]) {
    for (std::size_t i = 0; i < N; ++i) out[i] = Out(in[i]);
}

SumTree::WindingNodeT<float> to_float(const SumTree::WindingNodeT<double>& d) {
    SumTree::WindingNodeT<float> f;
    f.k0 = float(d.k0);
    narrow(f.m0, d.m0);
    narrow(f.p, d.p);
    narrow(f.s1, d.s1);
    narrow(f.t3, d.t3);
    return f;
}

/// The screened kernel f(r) = e^(−λ(r − r_min))/r and its first two radial derivatives.
struct Radial {
    double f, f1, f2;
};
GSD_ALWAYS_INLINE Radial screened_radial(double ir, double lambda, double E) {
    return {E * ir, -E * (lambda * ir + ir * ir), E * (lambda * lambda * ir + 2 * lambda * ir * ir + 2 * ir * ir * ir)};
}

/// Second-order expansion of Σ v_j K(x − y) about c (vector result), d = x − c:
/// X_a = M0_a f − f1 (M1_a·u) + ½ (A uᵀM2_a u + B tr M2_a), A = f2 − f1/r, B = f1/r.
GSD_ALWAYS_INLINE void screened_expansion(const double* m0, const double* m1, const double* m2, const Vec3& d, double r, const SumTree::Screened& k,
                        double E, Vec3& X) {
    const double ir = 1 / r;
    const Vec3 u = d * ir;
    const Radial f = screened_radial(ir, k.lambda, E);
    const double A = f.f2 - f.f1 * ir, B = f.f1 * ir;
    for (int a = 0; a < 3; ++a) {
        const double* m1a = m1 + 3 * a;
        const double* m2a = m2 + 6 * a;
        X[a] += m0[a] * f.f - f.f1 * (m1a[0] * u[0] + m1a[1] * u[1] + m1a[2] * u[2]) + 0.5 * (A * quad(m2a, u) + B * trace(m2a));
    }
}

/// The same expansion for a piece of one triangle: its moments are its vector area v times
/// (1, 0, covariance), so the bracket is one scalar for all three components.
GSD_ALWAYS_INLINE void screened_piece_expansion(const double* v, const double* cov, const Vec3& d, double r, const SumTree::Screened& k,
                              double E, Vec3& X) {
    const double ir = 1 / r;
    const Vec3 u = d * ir;
    const Radial f = screened_radial(ir, k.lambda, E);
    const double A = f.f2 - f.f1 * ir, B = f.f1 * ir;
    const double w = f.f + 0.5 * (A * quad(cov, u) + B * trace(cov));
    for (int a = 0; a < 3; ++a) X[a] += v[a] * w;
}

// point_triangle_distance2's body, inlined into the walks (and so into their x86-64-v3 copies).
GSD_ALWAYS_INLINE double triangle_distance2(const Vec3& x, const Vec3& a, const Vec3& b, const Vec3& c) {
    // Closest point by Voronoi regions of the triangle (vertices, edges, face); degenerate
    // triangles (zero area) fall back to their three segments.
    const Vec3 ab = b - a, ac = c - a, ap = x - a;
    auto segment = [&](const Vec3& p, const Vec3& q) {
        const Vec3 e = q - p;
        const double l2 = e.squaredNorm();
        const double t = l2 > 0 ? std::clamp((x - p).dot(e) / l2, 0.0, 1.0) : 0.0;
        return (x - (p + t * e)).squaredNorm();
    };
    const Vec3 n = ab.cross(ac);
    if (!(n.squaredNorm() > 1e-30 * ab.squaredNorm() * ac.squaredNorm()))
        return std::min({segment(a, b), segment(b, c), segment(c, a)});
    const double d1 = ab.dot(ap), d2 = ac.dot(ap);
    if (d1 <= 0 && d2 <= 0) return ap.squaredNorm();
    const Vec3 bp = x - b;
    const double d3 = ab.dot(bp), d4 = ac.dot(bp);
    if (d3 >= 0 && d4 <= d3) return bp.squaredNorm();
    const double vc = d1 * d4 - d3 * d2;
    if (vc <= 0 && d1 >= 0 && d3 <= 0) return (x - (a + d1 / (d1 - d3) * ab)).squaredNorm();
    const Vec3 cp = x - c;
    const double d5 = ab.dot(cp), d6 = ac.dot(cp);
    if (d6 >= 0 && d5 <= d6) return cp.squaredNorm();
    const double vb = d5 * d2 - d1 * d6;
    if (vb <= 0 && d2 >= 0 && d6 <= 0) return (x - (a + d2 / (d2 - d6) * ac)).squaredNorm();
    const double va = d3 * d6 - d5 * d4;
    if (va <= 0 && d4 - d3 >= 0 && d5 - d6 >= 0) return (x - (b + (d4 - d3) / ((d4 - d3) + (d5 - d6)) * (c - b))).squaredNorm();
    const double s = n.dot(ap);
    return s * s / n.squaredNorm();
}

}  // namespace

double point_triangle_distance2(const Vec3& x, const Vec3& a, const Vec3& b, const Vec3& c) { return triangle_distance2(x, a, b, c); }

double triangle_winding(const Vec3& x, const Vec3& a0, const Vec3& b0, const Vec3& c0) {
    return detail::triangle_solid_angle(x, a0, b0, c0) / kFourPi;
}


SumTree::SumTree(const OrientedElements& e) {
    e.validate();
    const std::size_t n = e.size();
    // Measured at 10⁶ elements (whole process, the input included): 793 B per face and 852 B per
    // point for `gsd winding`, 969 B and 1046 B for `gsd shm grid` (up to 3 nodes per element,
    // each with its moments and the float32 walk's records; the double walk's and SHM's records
    // come on demand); docs/io.md.
    check_memory(1152.0 * double(n), "elements", "a summation tree over " + std::to_string(n) + " elements");
    Points centroids(Eigen::Index(n), 3);
    for (std::size_t j = 0; j < n; ++j) {
        const auto J = Eigen::Index(j);
        centroids.row(J) = (e.corners.row(3 * J) + e.corners.row(3 * J + 1) + e.corners.row(3 * J + 2)) / 3;
    }
    const spatial::BoxTree tree(centroids, kLeafSize);
    order_ = tree.order();
    first_leaf_ = tree.first_leaf();
    p_.resize(9 * n);
    v_.resize(3 * n);
    cov_.resize(6 * n);
    is_point_.resize(n);
    bool triangles = false;
#pragma omp parallel for schedule(static) reduction(|| : triangles)
    for (std::size_t j = 0; j < n; ++j) {
        const auto J = Eigen::Index(order_[j]);
        for (int k = 0; k < 3; ++k)
            for (int a = 0; a < 3; ++a) p_[9 * j + std::size_t(3 * k + a)] = e.corners(3 * J + k, a);
        for (int a = 0; a < 3; ++a) v_[3 * j + std::size_t(a)] = e.vectors(J, a);
        double cov[6];
        triangle_covariance(&p_[9 * j], cov);
        std::copy(cov, cov + 6, &cov_[6 * j]);
        is_point_[j] = e.corners.row(3 * J) == e.corners.row(3 * J + 1) && e.corners.row(3 * J) == e.corners.row(3 * J + 2);
        triangles = triangles || !is_point_[j];
    }
    triangles_ = triangles;
    nodes_.resize(tree.nodes().size());
#pragma omp parallel for schedule(static)
    for (std::size_t i = 0; i < nodes_.size(); ++i) {
        nodes_[i].begin = tree.nodes()[i].begin;
        nodes_[i].end = tree.nodes()[i].end;
    }
    // Leaves from their elements, then each level of inner nodes from its children's moments,
    // translated to the node's center: O(n) instead of every node from its own elements,
    // O(n log n) (which took 35 % of a winding run's fixed cost on 1.3·10⁵ triangles). The
    // translation is exact algebra; only ρ needs every corner again (merge_node()).
#pragma omp parallel for schedule(static)
    for (std::size_t i = first_leaf_; i < nodes_.size(); ++i) compute_node(std::uint32_t(i));
    for (std::size_t level_end = first_leaf_; level_end > 0; level_end = (level_end - 1) / 2) {
        const std::size_t level_begin = (level_end - 1) / 2;  // the level above [level_end, …)
#pragma omp parallel for schedule(dynamic, 64) if (level_end - level_begin > 1024)
        for (std::size_t i = level_begin; i < level_end; ++i) merge_node(std::uint32_t(i));
    }
    // The winding walk's coordinates: centered on the root, in units of its radius.
    std::copy(nodes_[0].c, nodes_[0].c + 3, w_origin_);
    w_scale_ = nodes_[0].rho > 0 ? 1 / nodes_[0].rho : 1.0;
    // The float32 records every walk reads; the double ones and the screened sums' `Hot`
    // records are made when first needed (double_walk_data(), hot()): each a pass over the
    // nodes and tens of MB that most runs never touch.
    wnodes_f_.resize(nodes_.size());
    wtests_f_.resize(nodes_.size());
#pragma omp parallel for schedule(static)
    for (std::size_t i = 0; i < nodes_.size(); ++i) {
        const Node nd = normalized(nodes_[i], w_origin_, w_scale_);
        const auto t = winding_test(nd);
        wnodes_f_[i] = to_float(winding_node(nd));
        // ρ and q rounded up, so float32 never accepts a node that double would refuse for them.
        auto up = [](double v) { return float(v) < v ? std::nextafter(float(v), INFINITY) : float(v); };
        wtests_f_[i] = {{float(t.c[0]), float(t.c[1]), float(t.c[2])}, up(t.rho), up(t.q)};
    }
    elem_rho_.resize(n);
#pragma omp parallel for schedule(static)
    for (std::size_t j = 0; j < n; ++j) {
        const double* p = corners(j);
        const Vec3 g = (vec(p) + vec(p + 3) + vec(p + 6)) / 3;
        elem_rho_[j] = std::max({(vec(p) - g).norm(), (vec(p + 3) - g).norm(), (vec(p + 6) - g).norm()});
    }
}

void SumTree::double_walk_data() const {
    std::call_once(once_->twice, [this] {
        wnodes_.resize(nodes_.size());
        wtests_.resize(nodes_.size());
#pragma omp parallel for schedule(static)
        for (std::size_t i = 0; i < nodes_.size(); ++i) {
            const Node nd = normalized(nodes_[i], w_origin_, w_scale_);
            wnodes_[i] = winding_node(nd);
            wtests_[i] = winding_test(nd);
        }
    });
}

const std::vector<SumTree::Hot>& SumTree::hot() const {
    std::call_once(once_->hot, [this] {
        hot_.resize(nodes_.size());
#pragma omp parallel for schedule(static)
        for (std::size_t i = 0; i < nodes_.size(); ++i) {
            const Node& nd = nodes_[i];
            Hot& h = hot_[i];
            std::copy(nd.c, nd.c + 3, h.c);
            std::copy(nd.lo, nd.lo + 3, h.lo);
            std::copy(nd.hi, nd.hi + 3, h.hi);
            h.rho = nd.rho;
            h.area = nd.area;
            h.decay = 1;
            h.begin = nd.begin;
            h.end = nd.end;
        }
    });
    return hot_;
}

void SumTree::prepare_screened(double lambda) {
    hot();
    for (Hot& h : hot_) h.decay = std::exp(-lambda * h.rho);
    elem_decay_.resize(elem_rho_.size());
    for (std::size_t j = 0; j < elem_rho_.size(); ++j) elem_decay_[j] = std::exp(-lambda * elem_rho_[j]);
    decay_lambda_ = lambda;
}

void SumTree::compute_node(std::uint32_t i) {
    Node& nd = nodes_[i];
    Vec3 lo = Vec3::Constant(INFINITY), hi = Vec3::Constant(-INFINITY), weighted = Vec3::Zero();
    double area = 0;
    for (std::uint32_t j = nd.begin; j < nd.end; ++j) {
        const double* p = corners(j);
        for (int k = 0; k < 3; ++k) {
            lo = lo.cwiseMin(vec(p + 3 * k));
            hi = hi.cwiseMax(vec(p + 3 * k));
        }
        const double a = vec(vector(j)).norm();
        weighted += a * (vec(p) + vec(p + 3) + vec(p + 6)) / 3;
        area += a;
    }
    // Center: the area-weighted centroid (it makes M1 small); the box center if no area.
    const Vec3 c = area > 0 ? Vec3(weighted / area) : Vec3(0.5 * (lo + hi));
    double rho = 0;
    for (int a = 0; a < 3; ++a) { nd.m0[a] = 0; }
    std::fill(std::begin(nd.m1), std::end(nd.m1), 0.0);
    std::fill(std::begin(nd.m2), std::end(nd.m2), 0.0);
    for (std::uint32_t j = nd.begin; j < nd.end; ++j) {
        const double* p = corners(j);
        for (int k = 0; k < 3; ++k) rho = std::max(rho, (vec(p + 3 * k) - c).norm());
        const Vec3 s = (vec(p) + vec(p + 3) + vec(p + 6)) / 3 - c;
        const double* cov = covariance(j);
        const double second[6] = {s[0] * s[0] + cov[0], s[1] * s[1] + cov[1], s[2] * s[2] + cov[2],
                                  s[0] * s[1] + cov[3], s[0] * s[2] + cov[4], s[1] * s[2] + cov[5]};
        const double* v = vector(j);
        for (int a = 0; a < 3; ++a) {
            nd.m0[a] += v[a];
            for (int b = 0; b < 3; ++b) nd.m1[3 * a + b] += v[a] * s[b];
            for (int b = 0; b < 6; ++b) nd.m2[6 * a + b] += v[a] * second[b];
        }
    }
    for (int a = 0; a < 3; ++a) {
        nd.lo[a] = lo[a];
        nd.hi[a] = hi[a];
        nd.c[a] = c[a];
    }
    nd.rho = rho;
    nd.area = area;
}

void SumTree::merge_node(std::uint32_t i) {
    Node& nd = nodes_[i];
    const Node* kids[2] = {&nodes_[2 * i + 1], &nodes_[2 * i + 2]};
    double lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY}, weighted[3] = {0, 0, 0};
    double area = 0;
    for (const Node* k : kids) {
        if (k->begin == k->end) continue;
        for (int a = 0; a < 3; ++a) {
            lo[a] = std::min(lo[a], k->lo[a]);
            hi[a] = std::max(hi[a], k->hi[a]);
            weighted[a] += k->area * k->c[a];
        }
        area += k->area;
    }
    // Center: the area-weighted centroid, as compute_node() makes it; the box center if no area.
    for (int a = 0; a < 3; ++a) {
        nd.lo[a] = lo[a];
        nd.hi[a] = hi[a];
        nd.c[a] = area > 0 ? weighted[a] / area : 0.5 * (lo[a] + hi[a]);
        nd.m0[a] = 0;
    }
    nd.area = area;
    std::fill(std::begin(nd.m1), std::end(nd.m1), 0.0);
    std::fill(std::begin(nd.m2), std::end(nd.m2), 0.0);
    // s = y − c = (y − c_k) + δ with δ = c_k − c, so M1_a += M1k_a + M0k_a δ and
    // M2_a += M2k_a + M1k_a ⊗ δ + δ ⊗ M1k_a + M0k_a δδᵀ (the covariances ride along in M2k).
    static constexpr int pair[6][2] = {{0, 0}, {1, 1}, {2, 2}, {0, 1}, {0, 2}, {1, 2}};
    for (const Node* k : kids) {
        if (k->begin == k->end) continue;
        const double d[3] = {k->c[0] - nd.c[0], k->c[1] - nd.c[1], k->c[2] - nd.c[2]};
        for (int a = 0; a < 3; ++a) {
            nd.m0[a] += k->m0[a];
            for (int b = 0; b < 3; ++b) nd.m1[3 * a + b] += k->m1[3 * a + b] + k->m0[a] * d[b];
            for (int b = 0; b < 6; ++b) {
                const int x = pair[b][0], y = pair[b][1];
                nd.m2[6 * a + b] += k->m2[6 * a + b] + k->m1[3 * a + x] * d[y] + k->m1[3 * a + y] * d[x] + k->m0[a] * d[x] * d[y];
            }
        }
    }
    // ρ: the farthest corner below, compared squared (one square root).
    double far2 = 0;
    for (std::uint32_t j = nd.begin; j < nd.end; ++j) {
        const double* p = corners(j);
        for (int k = 0; k < 3; ++k) {
            const double x = p[3 * k] - nd.c[0], y = p[3 * k + 1] - nd.c[1], z = p[3 * k + 2] - nd.c[2];
            far2 = std::max(far2, x * x + y * y + z * z);
        }
    }
    nd.rho = std::sqrt(far2);
}

// The walk compiled twice: for every x86-64, and for CPUs with AVX2 and FMA (chosen once at
// run time), where the lane masks come from one vmovmskps/pd per register instead of a sum.
#define GSD_WALK_FN winding_lanes_generic
#define GSD_WALK_MASK lanes_greater
#include "sums/winding_walk.inl"
#undef GSD_WALK_FN
#undef GSD_WALK_MASK

#if defined(__x86_64__) && defined(__GNUC__)
#if defined(__clang__)
#pragma clang attribute push(__attribute__((target("avx2,fma"))), apply_to = function)
#else
#pragma GCC push_options
#pragma GCC target("avx2,fma")
#endif
GSD_ALWAYS_INLINE std::uint32_t lanes_greater_avx2(const float* d, float r) {
    static_assert(SumTree::kLanes == 8, "one AVX register of float32 lanes");
    return std::uint32_t(_mm256_movemask_ps(_mm256_cmp_ps(_mm256_load_ps(d), _mm256_set1_ps(r), _CMP_GT_OQ)));
}
GSD_ALWAYS_INLINE std::uint32_t lanes_greater_avx2(const double* d, double r) {
    const __m256d b = _mm256_set1_pd(r);
    return std::uint32_t(_mm256_movemask_pd(_mm256_cmp_pd(_mm256_load_pd(d), b, _CMP_GT_OQ))) |
           std::uint32_t(_mm256_movemask_pd(_mm256_cmp_pd(_mm256_load_pd(d + 4), b, _CMP_GT_OQ))) << 4;
}
#define GSD_WALK_FN winding_lanes_avx2
#define GSD_WALK_MASK lanes_greater_avx2
#include "sums/winding_walk.inl"
#undef GSD_WALK_FN
#undef GSD_WALK_MASK
#if defined(__clang__)
#pragma clang attribute pop
#else
#pragma GCC pop_options
#endif
#endif

struct WindingDispatch {
    template <class Real>
    static void run(const SumTree& t, const std::uint32_t* s, std::size_t c, const double* x, const double* y, const double* z,
                    int n, double beta, double tol, double* w, std::size_t& terms) {
#if defined(__x86_64__) && defined(__GNUC__)
        static const bool avx2 = __builtin_cpu_supports("avx2") && __builtin_cpu_supports("fma");
        if (avx2) return t.winding_lanes_avx2<Real>(s, c, x, y, z, n, beta, tol, w, terms);
#endif
        t.winding_lanes_generic<Real>(s, c, x, y, z, n, beta, tol, w, terms);
    }
};

bool SumTree::single_reach(double x, double y, double z) const {
    const double r = kSingleReach / w_scale_;
    return std::abs(x - w_origin_[0]) <= r && std::abs(y - w_origin_[1]) <= r && std::abs(z - w_origin_[2]) <= r;
}

void SumTree::walk(bool single, const std::uint32_t* starts, std::size_t count, const double* x, const double* y,
                   const double* z, int n, double beta, double tolerance, double* w, std::size_t& terms) const {
    if (n <= 0) return;
    if (n > kLanes) throw Error("packet", "more than " + std::to_string(kLanes) + " queries");
    single = single && single_enough(beta, tolerance);
    for (int l = 0; l < n && single; ++l) single = single_reach(x[l], y[l], z[l]);
    if (!single) double_walk_data();
    const std::uint32_t root = 0;
    if (single) WindingDispatch::run<float>(*this, starts, count, x, y, z, n, beta, tolerance, w, terms);
    // Double walks start from the root: frontiers are made for float walks only.
    else WindingDispatch::run<double>(*this, &root, 1, x, y, z, n, beta, tolerance, w, terms);
}

void SumTree::winding(const double* x, const double* y, const double* z, int n, double beta, double tolerance, double* w,
                      std::size_t& terms, bool single) const {
    const std::uint32_t root = 0;
    walk(single, &root, 1, x, y, z, n, beta, tolerance, w, terms);
}

void SumTree::winding_from(const WindingFrontier& frontier, const double* x, const double* y, const double* z, int n,
                           double beta, double tolerance, double* w, std::size_t& terms) const {
    // A frontier made for double walks is the root's (frontier_in is not run for them), so
    // walk() restarting those at the root loses nothing.
    walk(frontier.single, frontier.nodes.data(), frontier.nodes.size(), x, y, z, n, beta, tolerance, w, terms);
}

void SumTree::frontier_in(const double* lo, const double* hi, double beta, double tolerance, std::vector<std::uint32_t>& nodes) const {
    using Real = float;  // the float32 walk's records and arithmetic: only float walks start from a frontier
    const WindingTestT<Real>* tests = wtests_f_.data();
    // The box in the walk's coordinates, rounded as the lanes round their queries: every
    // query's coordinate stays within the box's (rounding is monotone).
    Real blo[3], bhi[3];
    for (int a = 0; a < 3; ++a) {
        blo[a] = Real((lo[a] - w_origin_[a]) * w_scale_);
        bhi[a] = Real((hi[a] - w_origin_[a]) * w_scale_);
    }
    const Real reach_scale = Real(sums::winding_reach_scale(tolerance)), beta_r = Real(beta);
    // The lanes may round their squared distance and reach (fused or not) a few units in the
    // last place away from this scalar code: only a node opened with that much room is skipped.
    constexpr Real margin = 1 + 16 * std::numeric_limits<Real>::epsilon();
    std::uint32_t stack[kStack];
    int top = 0;
    stack[top++] = 0;
    while (top > 0) {
        const std::uint32_t i = stack[--top];
        const WindingTestT<Real>& t = tests[i];
        // The farthest point of the box from the node's center.
        Real far2 = 0;
        for (int a = 0; a < 3; ++a) {
            const Real e = std::max(t.c[a] - blo[a], bhi[a] - t.c[a]);
            far2 += e * e;
        }
        if (i < first_leaf_ && far2 * margin <= sums::winding_reach2(t.rho, t.q, beta_r, reach_scale)) {
            stack[top++] = 2 * i + 1;  // every query in the box opens it: on to its children, in
            stack[top++] = 2 * i + 2;  // the order the walk takes them (the second child first)
        } else {
            nodes.push_back(i);
        }
    }
}

void SumTree::winding_frontier(const double* lo, const double* hi, double beta, double tolerance, WindingFrontier& frontier) const {
    frontier.nodes.clear();
    frontier.single = single_enough(beta, tolerance) && single_reach(lo[0], lo[1], lo[2]) && single_reach(hi[0], hi[1], hi[2]);
    // Double walks (queries far from the model, which open few nodes, or criteria finer than
    // float32) start from the root.
    if (frontier.single) frontier_in(lo, hi, beta, tolerance, frontier.nodes);
    else frontier.nodes.push_back(0);
}

double SumTree::winding(const Vec3& x, double beta, double tolerance, std::size_t& terms) const {
    double w = 0;
    winding(&x[0], &x[1], &x[2], 1, beta, tolerance, &w, terms);
    return w;
}

double SumTree::element_winding(const Vec3& x, std::size_t j) const {
    const double* p = corners(j);
    if (is_point_[j]) return point_winding_lane(x[0], x[1], x[2], p, vector(j));
    return sums::triangle_winding(x, vec(p), vec(p + 3), vec(p + 6));
}

double SumTree::winding_exact(const Vec3& x) const {
    double w = 0;
    for (std::size_t j = 0; j < size(); ++j) w += element_winding(x, j);
    return w;
}

double SumTree::nearest_distance(const Vec3& x, double bound, std::uint32_t* nearest) const {
    double r_min;
    nearest_lanes(x.data(), 1, &bound, nearest, &r_min);
    return r_min;
}

double SumTree::element_distance(const Vec3& x, std::uint32_t j) const {
    const double* c = corners(j);
    return std::sqrt(triangle_distance2(x, vec(c), vec(c + 3), vec(c + 6)));
}

template <int L, class Element2>
GSD_CLONES_V3 void SumTree::nearest_walk(const double* p, int n, const double* r_bound, std::uint32_t* nearest, double* r_min,
                           std::uint32_t* each, Element2&& element2_of) const {
    const std::vector<Hot>& records = hot();
    alignas(32) double q[3][L], best2[L];
    std::uint32_t best[L];
    for (int l = 0; l < L; ++l) {
        const int s = l < n ? l : 0;  // idle lanes repeat lane 0 and are masked off
        for (int a = 0; a < 3; ++a) q[a][l] = p[3 * s + a];
        const double bound = r_bound ? r_bound[s] : INFINITY;
        // Slightly above the bound so rounding never prunes the element that attains it.
        best2[l] = bound < INFINITY ? bound * bound * (1 + 1e-9) + 1e-300 : INFINITY;
        best[l] = std::uint32_t(-1);
    }
    auto element2 = [&](std::uint32_t j, int l) { return element2_of(j, l, q); };
    const std::uint32_t all = (1u << n) - 1;
    if (nearest && *nearest < size())  // a candidate's own distance: the search only looks for better
        for (int l = 0; l < n; ++l) {
            const double d2 = element2(*nearest, l);
            if (d2 < best2[l]) {
                best2[l] = d2;
                best[l] = *nearest;
            }
        }
    // Each entry carries its box's squared distance from every lane, measured when it was
    // pushed (∞ for lanes that do not visit it): popping it only compares those with the lanes'
    // best so far, and the parent orders its children by the distances it measured anyway.
    struct Entry {
        alignas(32) double box2[L];
        std::uint32_t node;
    };
    Entry stack[kStack];
    int top = 0;
    auto push = [&](std::uint32_t node, std::uint32_t lanes) {
        Entry& e = stack[top];
        const Hot& h = records[node];
#pragma omp simd
        for (int l = 0; l < L; ++l) e.box2[l] = box_distance2(h, q, l);
        for (int l = 0; l < L; ++l)
            if (!(lanes >> l & 1)) e.box2[l] = INFINITY;
        e.node = node;
        return &e;
    };
    auto live_lanes = [&](const double* box2) {
        std::uint32_t live = 0;
        for (int l = 0; l < L; ++l) live |= std::uint32_t(box2[l] < best2[l]) << l;
        return live;
    };
    push(0, all);
    ++top;
    while (top > 0) {
        const Entry& e = stack[--top];
        const std::uint32_t live = live_lanes(e.box2);
        if (!live) continue;
        const std::uint32_t node = e.node;
        if (node >= first_leaf_) {
            const Hot& h = records[node];
            for (std::uint32_t j = h.begin; j < h.end; ++j)
                for (std::uint32_t m = live; m; m &= m - 1) {
                    const int l = __builtin_ctz(m);
                    const double d2 = element2(j, l);
                    if (d2 < best2[l]) {
                        best2[l] = d2;
                        best[l] = j;
                    }
                }
            continue;
        }
        // The child nearer to the first live lane on top: it most likely holds the nearest
        // element, whose distance then prunes the other. (Pushing writes over the entry just
        // popped: `node` and `live` were read out of it.)
        const int l0 = __builtin_ctz(live);
        Entry& lower = *push(2 * node + 1, live);
        ++top;
        Entry& upper = *push(2 * node + 2, live);
        ++top;
        if (lower.box2[l0] <= upper.box2[l0]) std::swap(lower, upper);
        // What no lane reaches is dropped.
        const bool keep_lower = live_lanes(lower.box2) != 0, keep_upper = live_lanes(upper.box2) != 0;
        top -= 2;
        if (keep_lower) ++top;
        if (keep_upper) stack[top++] = upper;
    }
    for (int l = 0; l < n; ++l) r_min[l] = std::sqrt(best2[l]);
    if (each)
        for (int l = 0; l < n; ++l) each[l] = best[l];
    if (nearest) *nearest = best[n - 1];
}

GSD_CLONES_V3
void SumTree::nearest_lanes(const double* p, int n, const double* r_bound, std::uint32_t* nearest, double* r_min,
                            std::uint32_t* each) const {
    nearest_walk<kScreenedLanes>(p, n, r_bound, nearest, r_min, each, [&](std::uint32_t j, int l, const double (*q)[kScreenedLanes]) {
        const double* c = corners(j);
        return triangle_distance2(Vec3(q[0][l], q[1][l], q[2][l]), vec(c), vec(c + 3), vec(c + 6));
    });
}

const std::vector<SumTree::NearRecord>& SumTree::near_records() const {
    std::call_once(once_->near, [this] {
        near_.resize(size());
#pragma omp parallel for schedule(static)
        for (std::size_t j = 0; j < size(); ++j) {
            const double* c = corners(j);
            const Vec3 a = vec(c), ab = vec(c + 3) - a, ac = vec(c + 6) - a, n = ab.cross(ac);
            NearRecord& r = near_[j];
            r.flat = !(n.squaredNorm() > 1e-30 * ab.squaredNorm() * ac.squaredNorm());  // as point_triangle_distance2
            const Vec3 u = r.flat ? Vec3::Zero() : Vec3(n.normalized());
            for (int k = 0; k < 3; ++k) {
                r.a[k] = a[k];
                r.ab[k] = ab[k];
                r.ac[k] = ac[k];
                r.n[k] = u[k];
            }
            r.d00 = ab.squaredNorm();
            r.d01 = ab.dot(ac);
            r.d11 = ac.squaredNorm();
        }
    });
    return near_;
}

void SumTree::nearest_triangles(const double* p, int n, std::uint32_t* nearest, double* r_min, std::uint32_t* each) const {
    const std::vector<NearRecord>& rec = near_records();
    nearest_walk<kNearestLanes>(p, n, nullptr, nearest, r_min, each, [&](std::uint32_t j, int l, const double (*q)[kNearestLanes]) {
        const NearRecord& r = rec[j];
        const double x[3] = {q[0][l], q[1][l], q[2][l]};
        if (r.flat) {
            const double* c = corners(j);
            return triangle_distance2(Vec3(x[0], x[1], x[2]), vec(c), vec(c + 3), vec(c + 6));
        }
        // point_triangle_distance2's Voronoi regions, with d3 … d6 from d1, d2 and the records'
        // dot products (bp = ap − ab, cp = ap − ac).
        const double ap[3] = {x[0] - r.a[0], x[1] - r.a[1], x[2] - r.a[2]};
        const double d1 = r.ab[0] * ap[0] + r.ab[1] * ap[1] + r.ab[2] * ap[2];
        const double d2 = r.ac[0] * ap[0] + r.ac[1] * ap[1] + r.ac[2] * ap[2];
        auto dist2 = [&](double s, double t) {  // |ap − s·ab − t·ac|²
            const double e0 = ap[0] - s * r.ab[0] - t * r.ac[0], e1 = ap[1] - s * r.ab[1] - t * r.ac[1],
                         e2 = ap[2] - s * r.ab[2] - t * r.ac[2];
            return e0 * e0 + e1 * e1 + e2 * e2;
        };
        if (d1 <= 0 && d2 <= 0) return dist2(0, 0);
        const double d3 = d1 - r.d00, d4 = d2 - r.d01;
        if (d3 >= 0 && d4 <= d3) return dist2(1, 0);
        const double vc = d1 * d4 - d3 * d2;
        if (vc <= 0 && d1 >= 0 && d3 <= 0) return dist2(d1 / (d1 - d3), 0);
        const double d5 = d1 - r.d01, d6 = d2 - r.d11;
        if (d6 >= 0 && d5 <= d6) return dist2(0, 1);
        const double vb = d5 * d2 - d1 * d6;
        if (vb <= 0 && d2 >= 0 && d6 <= 0) return dist2(0, d2 / (d2 - d6));
        const double va = d3 * d6 - d5 * d4;
        if (va <= 0 && d4 - d3 >= 0 && d5 - d6 >= 0) {
            const double w = (d4 - d3) / ((d4 - d3) + (d5 - d6));
            return dist2(1 - w, w);
        }
        const double h = r.n[0] * ap[0] + r.n[1] * ap[1] + r.n[2] * ap[2];
        return h * h;
    });
}

Vec3 SumTree::screened(const Vec3& x, const Screened& k, double& r_min, std::size_t& terms, double r_bound,
                       std::uint32_t* nearest) const {
    Vec3 X;
    screened(x.data(), 1, k, &r_min, X.data(), terms, &r_bound, nearest);
    return X;
}

GSD_CLONES_V3
void SumTree::screened(const double* p, int n, const Screened& k, double* r_min, double* X, std::size_t& terms,
                       const double* r_bound, std::uint32_t* nearest) const {
    constexpr int L = kScreenedLanes;
    if (n <= 0) return;
    if (n > L) throw Error("packet", "more than " + std::to_string(L) + " queries");
    nearest_lanes(p, n, r_bound, nearest, r_min);
    const std::vector<Hot>& records = hot();
    const double budget = k.tolerance * 2 * M_PI / k.lambda;
    const bool cached = decay_lambda_ == k.lambda;
    alignas(32) double q[3][L], rmin[L], R[L], sum[3][L];  // R: the reach, r_min + cutoff/λ
    for (int l = 0; l < L; ++l) {
        const int s = l < n ? l : 0;
        for (int a = 0; a < 3; ++a) {
            q[a][l] = p[3 * s + a];
            sum[a][l] = 0;
        }
        rmin[l] = r_min[s];
        R[l] = rmin[l] + k.cutoff / k.lambda;
    }
    struct Entry { std::uint32_t node, lanes; };
    Entry stack[kStack];
    int top = 0;
    stack[top++] = {0, (1u << n) - 1};
    while (top > 0) {
        const Entry e = stack[--top];
        const Hot& nd = records[e.node];
        alignas(32) double box2[L], dx[L], dy[L], dz[L], dn[L];
        const double four_rho2 = 4 * nd.rho * nd.rho;
#pragma omp simd
        for (int l = 0; l < L; ++l) {
            box2[l] = box_distance2(nd, q, l);
            dx[l] = q[0][l] - nd.c[0];
            dy[l] = q[1][l] - nd.c[1];
            dz[l] = q[2][l] - nd.c[2];
            const double d2 = dx[l] * dx[l] + dy[l] * dy[l] + dz[l] * dz[l];
            dn[l] = d2 > four_rho2 ? std::sqrt(d2) : 0.0;  // 0: too close, refused
        }
        std::uint32_t live = 0;  // the lanes within reach: every element farther weighs < e^(−cutoff) of the nearest
        for (int l = 0; l < L; ++l) live |= std::uint32_t(!(box2[l] > R[l] * R[l])) << l;
        live &= e.lanes;
        if (!live) continue;
        const double decay = cached ? nd.decay : std::exp(-k.lambda * nd.rho);
        std::uint32_t accepted = 0;
        alignas(32) double E[L] = {0, 0, 0, 0};
        for (std::uint32_t m = live; m; m &= m - 1) {
            const int l = __builtin_ctz(m);
            accepted |= std::uint32_t(sums::accept_screened(nd.rho, dn[l], nd.area, k.lambda, rmin[l], budget, decay, E[l])) << l;
        }
        if (accepted) {
            const Node& mo = nodes_[e.node];
            alignas(32) double t[3][L];
#pragma omp simd
            for (int l = 0; l < L; ++l) {
                const double r = accepted >> l & 1 ? dn[l] : 1.0;  // refused lanes: any finite value, discarded
                const Vec3 d(dx[l], dy[l], dz[l]);
                Vec3 add = Vec3::Zero();
                screened_expansion(mo.m0, mo.m1, mo.m2, d, r, k, E[l], add);
                for (int a = 0; a < 3; ++a) t[a][l] = add[a];
            }
            for (int a = 0; a < 3; ++a)
#pragma omp simd
                for (int l = 0; l < L; ++l) sum[a][l] += (accepted >> l & 1) ? t[a][l] : 0.0;
            terms += std::size_t(__builtin_popcount(accepted));
        }
        const std::uint32_t rest = live & ~accepted;
        if (!rest) continue;
        if (e.node < first_leaf_) {
            stack[top++] = {2 * e.node + 1, rest};
            stack[top++] = {2 * e.node + 2, rest};
            continue;
        }
        for (std::uint32_t j = nd.begin; j < nd.end; ++j)
            for (std::uint32_t m = rest; m; m &= m - 1) {
                const int l = __builtin_ctz(m);
                double xl[3] = {q[0][l], q[1][l], q[2][l]}, Xl[3] = {sum[0][l], sum[1][l], sum[2][l]};
                screened_element(j, xl, k, rmin[l], R[l], budget, Xl, terms);
                for (int a = 0; a < 3; ++a) sum[a][l] = Xl[a];
            }
    }
    for (int l = 0; l < n; ++l)
        for (int a = 0; a < 3; ++a) X[3 * l + a] = sum[a][l];
}

namespace {

/// A piece's covariance (triangle_covariance), from its corners.
void piece_covariance(const Vec3& a, const Vec3& b, const Vec3& c, double (&cov)[6]) {
    const double p[9] = {a[0], a[1], a[2], b[0], b[1], b[2], c[0], c[1], c[2]};
    triangle_covariance(p, cov);
}

/// A piece's radius about its centroid g.
double piece_radius(const Vec3& a, const Vec3& b, const Vec3& c, const Vec3& g) {
    return std::sqrt(std::max({(a - g).squaredNorm(), (b - g).squaredNorm(), (c - g).squaredNorm()}));
}

}  // namespace

bool is_needle(const Vec3& a, const Vec3& b, const Vec3& c, double aspect) {
    const double longest2 = std::max({(b - a).squaredNorm(), (c - b).squaredNorm(), (a - c).squaredNorm()});
    return longest2 > aspect * (b - a).cross(c - a).norm();
}

GSD_CLONES_V3
void SumTree::screened_element(std::uint32_t j, const double* xp, const Screened& k, double r_min, double R, double budget,
                               double* Xp, std::size_t& terms) const {
    const double* p = corners(j);
    const Vec3 a = vec(p), b = vec(p + 3), c = vec(p + 6);
    const double* v = vector(j);
    const double rho0 = elem_rho_[j];
    if (rho0 <= R) {
        if (sums::is_needle(a, b, c, sums::kNeedleAspect)) {
            screened_needle(a, b, c, v, xp, k, r_min, R, budget, Xp, terms);
            return;
        }
        const double decay = decay_lambda_ == k.lambda ? elem_decay_[j] : std::exp(-k.lambda * rho0);
        screened_triangle(a, b - a, c - a, v, covariance(j), rho0, decay, xp, k, r_min, R, budget, Xp, terms);
        return;
    }
    // An element wider than the reach R: only its part within R of x weighs anything, and that
    // part lies in the cube of half-side R about x. Refining the whole element would cost what
    // its extent costs (a face with a stray corner at 4·10⁹ ran for hours); its part in the cube
    // costs what the reach holds. The cube's part, fanned into triangles, each refined as an
    // element of its own (vector area in proportion to its area).
    const Vec3 x = vec(xp), reach = Vec3::Constant(R);
    std::array<Vec3, 9> poly;
    const int n = detail::clip_triangle_to_box(a, b, c, x - reach, x + reach, poly);
    const double whole = (b - a).cross(c - a).norm();
    for (int i = 1; i + 1 < n; ++i) {
        const Vec3 &pa = poly[0], &pb = poly[std::size_t(i)], &pc = poly[std::size_t(i + 1)];
        const double share = (pb - pa).cross(pc - pa).norm() / whole;
        if (!(share > 0)) continue;
        const double vs[3] = {v[0] * share, v[1] * share, v[2] * share};
        if (sums::is_needle(pa, pb, pc, sums::kNeedleAspect)) {
            screened_needle(pa, pb, pc, vs, xp, k, r_min, R, budget, Xp, terms);
            continue;
        }
        double cov[6];
        piece_covariance(pa, pb, pc, cov);
        const double rho = piece_radius(pa, pb, pc, (pa + pb + pc) / 3);
        screened_triangle(pa, pb - pa, pc - pa, vs, cov, rho, std::exp(-k.lambda * rho), xp, k, r_min, R, budget, Xp, terms);
    }
}

GSD_CLONES_V3
void SumTree::screened_needle(const Vec3& a, const Vec3& b, const Vec3& c, const double* v, const double* xp,
                              const Screened& k, double r_min, double R, double budget, double* Xp, std::size_t& terms) {
    // The 1→4 split keeps a needle's shape: each piece is as thin as the needle, so its radius
    // — half its length — stays large next to its distance, and a node beside a long needle
    // refined thousands of pieces (a face with one corner moved 10³ edges away cost 1.2·10⁹
    // terms at 32³). Bisecting at the longest edge makes pieces of bounded shape within a few
    // levels: the pieces near x are then a handful a level. Each piece carries its own
    // corners, so its radius, share of the area and covariance come from them.
    struct Piece {
        Vec3 p[3];
        int level;
    };
    Piece pieces[2 * kNeedleLevels + 4];
    const Vec3 x = vec(xp);
    Vec3 X = vec(Xp);
    const double whole = (b - a).cross(c - a).norm();
    if (!(whole > 0)) return;  // no area to share out (elements with none are dropped earlier)
    const double area = std::sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
    int np = 0, splits = 0;
    pieces[np++] = {{a, b, c}, 0};
    while (np > 0) {
        const Piece q = pieces[--np];
        const Vec3 g = (q.p[0] + q.p[1] + q.p[2]) / 3;
        const double rho = piece_radius(q.p[0], q.p[1], q.p[2], g);
        const Vec3 dg = x - g;
        const double dist = dg.norm();
        if (dist - rho > R) continue;
        const double share = (q.p[1] - q.p[0]).cross(q.p[2] - q.p[0]).norm() / whole;
        const double m0[3] = {v[0] * share, v[1] * share, v[2] * share};
        double E;
        if (sums::accept_screened(rho, dist, area * share, k.lambda, r_min, budget, std::exp(-k.lambda * rho), E)) {
            double cov[6];  // only accepted pieces need it: most are split or out of reach
            piece_covariance(q.p[0], q.p[1], q.p[2], cov);
            screened_piece_expansion(m0, cov, dg, dist, k, E, X);
        } else if (rho <= k.r_floor || q.level >= kNeedleLevels || splits >= sums::kMaxSplits) {
            const double w = std::exp(-k.lambda * (dist - r_min)) / std::max(dist, k.r_floor);
            for (int i = 0; i < 3; ++i) X[i] += m0[i] * w;
        } else {
            // Corners i, i + 1 span the longest edge; the two halves keep the orientation.
            const double len[3] = {(q.p[1] - q.p[0]).squaredNorm(), (q.p[2] - q.p[1]).squaredNorm(), (q.p[0] - q.p[2]).squaredNorm()};
            const int i = int(std::max_element(len, len + 3) - len), j = (i + 1) % 3, o = (i + 2) % 3;
            const Vec3 mid = 0.5 * (q.p[i] + q.p[j]);
            ++splits;
            pieces[np++] = {{q.p[i], mid, q.p[o]}, q.level + 1};
            pieces[np++] = {{mid, q.p[j], q.p[o]}, q.level + 1};
            continue;
        }
        ++terms;
    }
    for (int i = 0; i < 3; ++i) Xp[i] = X[i];
}

GSD_CLONES_V3
void SumTree::screened_triangle(const Vec3& a, const Vec3& ab, const Vec3& ac, const double* v, const double* cov,
                                double rho0, double decay0, const double* xp, const Screened& k, double r_min, double R,
                                double budget, double* Xp, std::size_t& terms) {
    // One sub-triangle of the element being refined: barycentric origin (s, t), scale h and
    // orientation σ; its corners are o, o + σh e1, o + σh e2 in the (s, t) parameters of the
    // element (a + s (b − a) + t (c − a)). Children: the three corner triangles at h/2 and the
    // middle one, flipped — all similar to the element, so a piece's radius is h·ρ and its
    // e^(−λρ) the square root of its parent's.
    struct Piece { double s, t, h, sigma, decay; int level; };
    Piece pieces[3 * 20 + 8];
    const Vec3 x = vec(xp);
    Vec3 X = vec(Xp);
    const double area = std::sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
    int np = 0, splits = 0;
    pieces[np++] = {0, 0, 1, 1, decay0, 0};
    while (np > 0) {
        const Piece q = pieces[--np];
        const Vec3 g = a + (q.s + q.sigma * q.h / 3) * ab + (q.t + q.sigma * q.h / 3) * ac;
        const double rho = rho0 * q.h;
        const Vec3 dg = x - g;
        const double dist = dg.norm();
        if (dist - rho > R) continue;
        const double share = q.h * q.h;  // of the element's area
        const double m0[3] = {v[0] * share, v[1] * share, v[2] * share};
        double E;
        if (sums::accept_screened(rho, dist, area * share, k.lambda, r_min, budget, q.decay, E)) {
            double piece_cov[6];  // the piece's covariance: the element's, scaled like its area
            for (int b = 0; b < 6; ++b) piece_cov[b] = cov[b] * share;
            screened_piece_expansion(m0, piece_cov, dg, dist, k, E, X);
        } else if (rho <= k.r_floor || q.level >= 20 || splits >= sums::kMaxSplits) {
            // Small enough that 1/r no longer resolves it (or at the depth or split limit):
            // its centroid, at no closer than r_floor.
            const double w = std::exp(-k.lambda * (dist - r_min)) / std::max(dist, k.r_floor);
            for (int c = 0; c < 3; ++c) X[c] += m0[c] * w;
        } else {
            const double h = q.h / 2, sh = q.sigma * h, decay = std::sqrt(q.decay);
            ++splits;
            pieces[np++] = {q.s, q.t, h, q.sigma, decay, q.level + 1};
            pieces[np++] = {q.s + sh, q.t, h, q.sigma, decay, q.level + 1};
            pieces[np++] = {q.s, q.t + sh, h, q.sigma, decay, q.level + 1};
            pieces[np++] = {q.s + sh, q.t + sh, h, -q.sigma, decay, q.level + 1};
            continue;
        }
        ++terms;
    }
    for (int c = 0; c < 3; ++c) Xp[c] = X[c];
}

}  // namespace gsd::sums
