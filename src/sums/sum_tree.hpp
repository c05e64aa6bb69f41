// SumTree: the hierarchy behind every fast sum over oriented area elements (docs/sums.md has
// the algorithms and their accuracy). Elements are flat triangles of uniform density or points,
// each carrying a vector area v_j = A_j·N_j. A complete kd-tree over the element centroids (BoxTree's order)
// stores, per node, its expansion center c, the radius ρ of the ball around c that holds every
// corner, and the moments of the area distribution about c up to second order:
//
//   M0   = Σ_j v_j                                       (3)
//   M1_a = Σ_j v_j[a] (g_j − c)                          (3×3)
//   M2_a = Σ_j v_j[a] ((g_j − c)(g_j − c)ᵀ + C_j)         (3 × symmetric 3×3)
//
// with g_j the centroid and C_j = (1/12) Σ_corners (p − g_j)(p − g_j)ᵀ the covariance of a
// uniform triangle (0 for a point). A sum Σ_j v_j ⊗ K(x − y) over a well-separated node is
// then its second-order Taylor expansion about c, exact for the triangles' true area
// distribution (not their centroids) to that order.
//
// Two kernels use it: the screened kernel of the Signed Heat Method's step 1 (vector sum)
// and the dipole kernel of the generalized winding number (scalar). Private to the library;
// the GPU path uploads the same arrays as float (sums_gpu.hpp).
#pragma once

#include <gsd/sums.hpp>

#include "core/uninitialized.hpp"

#include <Eigen/Core>

#include <algorithm>
#include <cfloat>
#include <cmath>
#include <cstdint>
#include <memory>
#include <mutex>
#include <vector>

namespace gsd::sums {

class SumTree {
public:
    struct Node {
        double lo[3], hi[3];    ///< box of every corner below
        std::uint32_t begin, end;
        double c[3], rho;       ///< expansion center, radius of the ball around it holding every corner
        double area;            ///< Σ |v_j|
        double m0[3], m1[9], m2[18];  ///< m1[3a+i]; m2[6a + (xx yy zz xy xz yz)]
    };

    /// What a tree walk reads at every visit (48 + 48 + 8 bytes), apart from the moments it
    /// reads only when it sums a node: the walk stays in few cache lines.
    struct Hot {
        double c[3], rho, area, decay;  ///< decay: e^(−λρ) for the λ of prepare_screened()
        double lo[3], hi[3];
        std::uint32_t begin, end;
    };

    // The dipole kernel's derivatives are symmetric in all their indices, so its expansion needs
    // only the symmetric parts of the moments: tr M1, M0 (3), sym M1 (6), the symmetrized M2 as
    // a cubic form (10) and t + 2s (3; t_a = tr M2_a, s_j = Σ_a M2_a[a][j]), each scaled by its
    // factor in winding_expansion — one contiguous record per node. The winding walk reads these
    // in coordinates centered on the root and scaled by its radius (so that float32 keeps its
    // precision wherever the model is and whatever its size), in float32 or in double.
    template <class Real>
    struct WindingNodeT {
        Real k0, m0[3], p[3], s1[6], t3[10];
    };
    /// What the winding walk's acceptance test reads: center, ρ and the node's part of its
    /// reach, q = (A·ρ³/π)^(1/5) (sums::winding_reach2), in those coordinates.
    template <class Real>
    struct WindingTestT {
        Real c[3], rho, q;
    };
    /// Where a group of winding queries starts its walks (winding_frontier()).
    struct WindingFrontier {
        std::vector<std::uint32_t> nodes;
        bool single = true;  ///< the walks run their far field in float32
    };

    explicit SumTree(const OrientedElements& elements);
    /// Caches e^(−λρ) per node and element for screened sums with this λ (optional: screened()
    /// computes what is not cached).
    void prepare_screened(double lambda);

    const detail::UninitializedVector<Node>& nodes() const { return nodes_; }
    std::uint32_t first_leaf() const { return first_leaf_; }
    std::size_t size() const { return v_.size() / 3; }
    bool has_triangles() const { return triangles_; }
    /// Element j in tree order: corners (9 doubles: a, b, c; equal for a point) and vector area.
    const double* corners(std::size_t j) const { return &p_[9 * j]; }
    const double* vector(std::size_t j) const { return &v_[3 * j]; }
    /// Its covariance (1/12) Σ (p − g)(p − g)ᵀ as (xx yy zz xy xz yz); 0 for a point.
    const double* covariance(std::size_t j) const { return &cov_[6 * j]; }
    /// order()[j]: the caller's index of the j-th element in tree order.
    const std::vector<std::uint32_t>& order() const { return order_; }

    // ---- the winding-number (dipole) kernel --------------------------------------------
    /// Σ_j v_j·(y − x)/(4π|y − x|³) integrated over each element: nodes that accept_winding()
    /// allows by their expansion, the rest exactly (triangles by their solid angle). terms: +1
    /// per node expansion or element summed.
    double winding(const Eigen::Vector3d& x, double beta, double tolerance, std::size_t& terms) const;
    /// The same for a packet of up to kLanes nearby queries (x, y, z: n ≤ kLanes coordinates),
    /// which walk the tree together: a node is read once for the packet, and the acceptance
    /// tests and expansions run on every lane at once (SIMD; AVX2 where the CPU has it). Each
    /// lane visits the nodes its own walk would, in the same order, with the same arithmetic:
    /// its result does not depend on the other lanes (unless one of them makes the packet walk
    /// in double, below).
    ///
    /// Precision: the far field (acceptance tests and node expansions, 90 % of the terms) runs
    /// in float32 — 8 lanes per AVX2 register instead of 4 — in the root's normalized
    /// coordinates, which bounds its rounding error by ~1e-6 in the winding number; elements
    /// summed exactly run in double. Queries farther than kSingleReach root radii from the
    /// root's center (their far field could under- or overflow in float32) walk in double, and
    /// so do all queries when the criterion asks for more accuracy than float32 gives
    /// (single_enough()).
    static constexpr int kLanes = 8;
    static constexpr double kSingleReach = 1e4;
    /// `single` false walks the far field in double too (the reference for its precision).
    void winding(const double* x, const double* y, const double* z, int n, double beta, double tolerance, double* w,
                 std::size_t& terms, bool single = true) const;
    /// The nodes where the walk of any query in the box [lo, hi] first does something other
    /// than open the node: it skips every node that all of them would open (the farthest point
    /// of the box is within the node's reach, with a margin for rounding). In the order the walk
    /// from the root reaches them; for the precision the box's queries walk in.
    void winding_frontier(const double* lo, const double* hi, double beta, double tolerance, WindingFrontier& frontier) const;
    /// The packet walk started from the frontier of a box that holds the packet's queries: the
    /// same nodes, the same order and the same result as from the root, fewer visits.
    void winding_from(const WindingFrontier& frontier, const double* x, const double* y, const double* z, int n, double beta,
                      double tolerance, double* w, std::size_t& terms) const;
    /// The exact sum over every element (the reference).
    double winding_exact(const Eigen::Vector3d& x) const;
    /// A slot for the tree's copy on a device (sums_gpu.cpp keeps its uploaded records here, so
    /// that repeated calls on one field upload them once), and the lock that guards it.
    std::shared_ptr<void>& device_copy() const { return device_copy_; }
    std::mutex& device_copy_mutex() const { return once_->device; }
    /// The float32 walk's records, one per node (what the GPU walk uploads), and its
    /// coordinates: x ↦ (x − winding_origin())·winding_scale().
    const WindingTestT<float>* winding_tests_f() const { return wtests_f_.data(); }
    const WindingNodeT<float>* winding_nodes_f() const { return wnodes_f_.data(); }
    const double* winding_origin() const { return w_origin_; }
    double winding_scale() const { return w_scale_; }

    // ---- the screened kernel of SHM step 1 ---------------------------------------------
    struct Screened {
        double lambda = 0;  ///< 1/√t
        double cutoff = 8;  ///< drop what weighs less than e^(−cutoff) of the nearest element
        double r_floor = 0; ///< distances below this count as r_floor (1/r is singular)
        double tolerance = 0.3; ///< accuracy: see accept_screened()
    };
    /// Distance from x to the nearest element (exact point–triangle distance).
    /// `bound`: a known upper bound of it (e.g. a neighbor's distance plus the step: the
    /// distance is 1-Lipschitz), which prunes the search; exact either way.
    /// `nearest`, if given: in, an element index whose distance also bounds the search (the
    /// previous query's nearest, for a neighbor: usually the answer; ≥ size() for none); out,
    /// the element that attains the distance.
    double nearest_distance(const Eigen::Vector3d& x, double bound = INFINITY, std::uint32_t* nearest = nullptr) const;
    /// Distance from x to element j (what nearest_distance() minimizes): an upper bound of the
    /// nearest distance from one element, no search.
    double element_distance(const Eigen::Vector3d& x, std::uint32_t j) const;
    /// X = Σ_j v_j ∫ e^(−λ(r − r_min))/r dA_j / A_j over elements within r_min + cutoff/λ, by
    /// node expansions where accept_screened() says so and by adaptive subdivision of the
    /// triangles elsewhere. Returns X (only its direction matters) and sets r_min.
    /// r_bound, nearest: an upper bound of r_min and a start element, if known (see
    /// nearest_distance).
    Eigen::Vector3d screened(const Eigen::Vector3d& x, const Screened& k, double& r_min, std::size_t& terms,
                             double r_bound = INFINITY, std::uint32_t* nearest = nullptr) const;
    static constexpr int kScreenedLanes = 4;
    /// Queries per packet of nearest_triangles(): a far query's search opens many nodes near
    /// its nearest point, which its Morton neighbours open too; 16 share them. For 10⁶ queries
    /// around a 9·10⁴-face mesh, 2 threads: 1.86 s in packets of 4, 1.56 s of 8, 1.52 s of 16.
    static constexpr int kNearestLanes = 16;
    /// screened() for a packet of n ≤ kScreenedLanes nearby queries (p: 3n coordinates; X: 3n
    /// out; r_min: n out; r_bound: n upper bounds of r_min, or null; nearest: one start element
    /// for all, out: the last query's nearest). The nearest-element search and the tree walk
    /// are shared — the lanes that need a node read it once — while every query makes its own
    /// decisions and adds its own terms in the order screened() would: the results are the same.
    void screened(const double* p, int n, const Screened& k, double* r_min, double* X, std::size_t& terms,
                  const double* r_bound = nullptr, std::uint32_t* nearest = nullptr) const;

    /// nearest_distance() for a packet of n ≤ kScreenedLanes nearby queries (p: 3n coordinates),
    /// the walk shared as screened()'s is: r_min[l] for each; r_bound (may be null) and nearest as
    /// for screened(). Exact for every query.
    /// each (may be null): n out, every query's nearest element (tree order).
    void nearest_lanes(const double* p, int n, const double* r_bound, std::uint32_t* nearest, double* r_min,
                       std::uint32_t* each = nullptr) const;
    /// nearest_lanes() for the signed distance, n ≤ kNearestLanes (no bound; `each` as there): the same walk and
    /// the same nearest elements, each triangle's distance from a record made once (its corner,
    /// edges, their dot products and unit normal: two dot products with the query instead of
    /// six and a cross product). Distances agree with nearest_lanes()' to rounding.
    void nearest_triangles(const double* p, int n, std::uint32_t* nearest, double* r_min, std::uint32_t* each) const;

private:
    /// The walk of nearest_lanes() for packets of n ≤ L queries, with element j's squared
    /// distance to lane l's query from `element2(j, l, q)` (q: the packet's coordinates, [axis][lane]).
    template <int L, class Element2>
    void nearest_walk(const double* p, int n, const double* r_bound, std::uint32_t* nearest, double* r_min,
                      std::uint32_t* each, Element2&& element2) const;
    /// A triangle's record for nearest_triangles(): degenerate ones (and points) keep the
    /// general formula (`flat`).
    struct NearRecord {
        double a[3], ab[3], ac[3], n[3];  // n: unit normal
        double d00, d01, d11;             // ab·ab, ab·ac, ac·ac
        bool flat;
    };
    const std::vector<NearRecord>& near_records() const;
    mutable std::vector<NearRecord> near_;
    /// Element j's part of screened() at x: the triangle refined until its pieces pass; an
    /// element wider than the reach R, only its part in the cube of half-side R about x.
    void screened_element(std::uint32_t j, const double* x, const Screened& k, double r_min, double R, double budget,
                          double* X, std::size_t& terms) const;
    /// The refinement of a needle (sums::is_needle): pieces bisected at their longest edge.
    static constexpr int kNeedleLevels = 60;
    static void screened_needle(const Eigen::Vector3d& a, const Eigen::Vector3d& b, const Eigen::Vector3d& c, const double* v,
                                const double* x, const Screened& k, double r_min, double R, double budget, double* X,
                                std::size_t& terms);
    /// The refinement itself, for a triangle a, a + ab, a + ac with vector area v, covariance
    /// cov, radius ρ0 about its centroid and e^(−λρ0) = decay0.
    static void screened_triangle(const Eigen::Vector3d& a, const Eigen::Vector3d& ab, const Eigen::Vector3d& ac,
                                  const double* v, const double* cov, double rho0, double decay0, const double* x,
                                  const Screened& k, double r_min, double R, double budget, double* X, std::size_t& terms);
    void compute_node(std::uint32_t i);  ///< from its elements (the leaves)
    void merge_node(std::uint32_t i);    ///< from its children (inner nodes)
    /// Element j's exact term: its solid angle / 4π, or a point's dipole.
    double element_winding(const Eigen::Vector3d& x, std::size_t j) const;

    detail::UninitializedVector<Node> nodes_;  // every field written by compute_node() / merge_node()
    mutable std::vector<Hot> hot_;  // hot(): made on first use
    struct Once {
        std::once_flag hot, twice, near;
        std::mutex device;  // device_copy
    };
    std::unique_ptr<Once> once_ = std::make_unique<Once>();  // a pointer: SumTree stays movable
    mutable std::shared_ptr<void> device_copy_;
    const std::vector<Hot>& hot() const;
    /// Makes wnodes_ and wtests_ (the double walk's records) if they are not there yet.
    void double_walk_data() const;
    mutable std::vector<WindingNodeT<double>> wnodes_;  // double_walk_data()
    mutable std::vector<WindingTestT<double>> wtests_;
    detail::UninitializedVector<WindingNodeT<float>> wnodes_f_;
    detail::UninitializedVector<WindingTestT<float>> wtests_f_;
    double w_origin_[3] = {0, 0, 0}, w_scale_ = 1;  // the walk's coordinates: (x − origin)·scale
    /// Whether a query at (x, y, z) may walk in float32 (within kSingleReach of the root).
    bool single_reach(double x, double y, double z) const;
    /// Whether float32's ~1e-6 is far below the criterion's truncation error: tolerance ≥ 1e-4,
    /// or β ≤ 4 when tolerance is 0.
    static bool single_enough(double beta, double tolerance) { return tolerance > 0 ? tolerance >= 1e-4 : beta <= 4; }
    // The packet walk, compiled for any x86-64 and for AVX2 + FMA (sum_tree.cpp, winding_walk.inl).
    template <class Real>
    void winding_lanes_generic(const std::uint32_t* starts, std::size_t count, const double* x, const double* y, const double* z,
                               int n, double beta, double tolerance, double* w, std::size_t& terms) const;
    template <class Real>
    void winding_lanes_avx2(const std::uint32_t* starts, std::size_t count, const double* x, const double* y, const double* z,
                            int n, double beta, double tolerance, double* w, std::size_t& terms) const;
    void frontier_in(const double* lo, const double* hi, double beta, double tolerance, std::vector<std::uint32_t>& nodes) const;
    void walk(bool single, const std::uint32_t* starts, std::size_t count, const double* x, const double* y, const double* z, int n,
              double beta, double tolerance, double* w, std::size_t& terms) const;
    friend struct WindingDispatch;
    detail::UninitializedVector<double> elem_rho_, elem_decay_;  // per element: radius about its centroid, e^(−λρ)
    double decay_lambda_ = -1;
    std::uint32_t first_leaf_ = 0;
    detail::UninitializedVector<double> p_, v_, cov_;  // corners, vector areas, triangle covariances (6 each)
    std::vector<std::uint32_t> order_;
    std::vector<std::uint8_t> is_point_;  // per element: all three corners equal
    bool triangles_ = false;
};


/// A triangle whose longest edge squared exceeds `aspect` times twice its area (its length over
/// its height): SHM step 1 refines it by bisection (SumTree::screened_needle), not by 1→4
/// splits, and the GPU leaves the nodes near one to the CPU (shaders/shm_diffuse.comp tests
/// against kNeedleAspectGpu, lower, so that it never refines one the CPU would bisect). High
/// enough that real meshes rarely have one (the shared scans: 0–209 faces of thousands past
/// 256, 0–8 past 1024, most of them the fans of triangulated polygons), low enough for a stray
/// vertex's faces (10³–10⁹).
constexpr double kNeedleAspect = 1024, kNeedleAspectGpu = 768;
bool is_needle(const Eigen::Vector3d& a, const Eigen::Vector3d& b, const Eigen::Vector3d& c, double aspect);

/// The most splits one (query, element) pair's refinement makes (SumTree::screened_triangle and
/// shaders/shm_diffuse.comp alike): past it, pieces count by their centroids. A triangle within
/// the reach needs tens of splits and a needle of aspect 10³ hundreds; the cap bounds the
/// pathological rest (an element clipped to the reach is at most 2√3·R across).
constexpr int kMaxSplits = 4096;

/// Squared distance from x to the triangle (a, b, c) (degenerate triangles included).
double point_triangle_distance2(const Eigen::Vector3d& x, const Eigen::Vector3d& a, const Eigen::Vector3d& b,
                                const Eigen::Vector3d& c);
/// Signed solid angle of the triangle seen from x, / 4π (Van Oosterom–Strackee).
double triangle_winding(const Eigen::Vector3d& x, const Eigen::Vector3d& a, const Eigen::Vector3d& b,
                        const Eigen::Vector3d& c);

/// atan2 in plain arithmetic, so that a `simd` loop over lanes vectorizes it (libm's does not):
/// the octant by comparisons, atan on [−tan(π/8), tan(π/8)] (after t → (t − 1)/(t + 1) above
/// it) as t·P(t²). P: a degree-9 least-squares Chebyshev fit made for this function; measured
/// |error| < 1e-15 on its interval (tests/test_sums.cpp holds it to 4e-15 against std::atan2).
inline double atan2_lanes(double y, double x) {
    constexpr double kTanPi8 = 0.41421356237309503;
    constexpr double P[10] = {0.99999999999999845,   -0.3333333333324397,    0.19999999981562366,  -0.14285712811688819,
                              0.11111052344802114,   -0.090895740809928696, 0.076738442876498641, -0.065071130091290369,
                              0.050264795149734122,  -0.025317970239585298};
    const double ax = std::abs(x), ay = std::abs(y);
    const double hi = std::max(ax, ay), lo = std::min(ax, ay);
    // Arithmetic on every lane, then selects; no branch. hi = 0 (then lo = 0 too) divides by
    // the smallest normal number instead of by a selected value.
    const double t0 = lo / std::max(hi, DBL_MIN), t1 = (t0 - 1) / (t0 + 1);
    const bool shifted = t0 > kTanPi8;
    const double t = shifted ? t1 : t0;
    const double u = t * t;
    const double p =
        P[0] + u * (P[1] + u * (P[2] + u * (P[3] + u * (P[4] + u * (P[5] + u * (P[6] + u * (P[7] + u * (P[8] + u * P[9]))))))));
    double a = t * p + (shifted ? M_PI / 4 : 0.0);
    a = ay > ax ? M_PI / 2 - a : a;
    a = x < 0 ? M_PI - a : a;
    return std::copysign(a, y);
}

/// Whether a node of radius ρ and total area A (Σ|v_j|) at squared distance d2 from its center
/// may be summed by its second-order dipole expansion: d > β·ρ, and — when tolerance > 0 — the
/// Taylor remainder bound A·ρ³/(π(d − ρ)⁵) (from |∂⁴(1/4πr)| ≤ 24/(4πr⁵)) is at most
/// `tolerance`, an absolute error in the winding number per node. Branch-free, so the packet
/// walk's lane loop vectorizes with it.
inline bool accept_winding(double rho, double d2, double area, double beta, double tolerance) {
    const double g = std::sqrt(d2) - rho, g2 = g * g;
    return (d2 > beta * beta * rho * rho) & ((tolerance <= 0) | (area * rho * rho * rho <= tolerance * M_PI * g2 * g2 * g));
}

/// accept_winding() solved for the distance, so that the walk takes no square root to test a
/// node: with q = (A·ρ³/π)^(1/5) stored per node and s = tolerance^(−1/5) (0 for tolerance 0)
/// per walk, the node is accepted iff d² > reach², reach = max(β·ρ, ρ + q·s).
template <class Real>
inline Real winding_reach2(Real rho, Real q, Real beta, Real s) {
    const Real a = beta * rho, b = rho + q * s;
    return a > b ? a * a : b * b;
}
inline double winding_reach_scale(double tolerance) { return tolerance > 0 ? std::pow(tolerance, -0.2) : 0.0; }

/// Whether a cluster of radius ρ, total area A, whose center is at distance d may be summed
/// by its second-order expansion of the screened kernel f(r) = e^(−λ(r − r_min))/r. With
/// q = ρ(λ + 2/(d − ρ)) the third Taylor term bounds the truncation error by about
/// A·f(d − ρ)·q³/6 (f(d − ρ): the largest weight in the cluster). The cluster is accepted when
/// that bound is below `budget` = tolerance · 2π/λ — a fraction of |X| for any sheet-like
/// source (an infinite plane gives |X| = 2π/λ at every distance) — and d ≥ 2ρ.
/// decay = e^(−λρ); on acceptance E_d = e^(−λ(d − r_min)), the weight the expansion needs.
inline bool accept_screened(double rho, double d, double area, double lambda, double r_min, double budget,
                            double decay, double& E_d) {
    if (!(d > 2 * rho)) return false;
    E_d = std::exp(-lambda * (d - r_min));
    if (rho == 0) return true;
    // area·(E_d/decay)/gap·q³ ≤ 6·budget with q = ρ(λ·gap + 2)/gap, multiplied out (no division).
    const double gap = d - rho, s = rho * (lambda * gap + 2), g2 = gap * gap;
    return area * E_d * s * s * s <= 6 * budget * decay * g2 * g2;
}


}  // namespace gsd::sums
