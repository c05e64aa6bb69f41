// A point cloud as a surface for the surface methods (thesis fig. 4.5, left; Sharp & Crane 2020,
// "A Laplacian for nonmanifold triangle meshes", §5): every point gets the triangles of its
// neighbours' Delaunay triangulation in its tangent plane that have it as a corner, and the
// surface is the union of those little fans. Neighbouring fans mostly agree, so most triangles
// come three times (once from each corner); where they disagree both versions are kept. The
// operators are assembled face by face (src/surface_shm/operators.hpp), so the union is just a
// nonmanifold mesh to them, and its Laplacian is the sum of the points' local Laplacians — the
// point-cloud Laplacian of Sharp & Crane (up to their 1/3, which cancels against the masses).
#include <gsd/spatial.hpp>
#include <gsd/surface.hpp>

#include "spatial/morton.hpp"

#include <Eigen/Eigenvalues>

#include <algorithm>
#include <cmath>
#include <map>
#include <queue>
#include <unordered_set>

namespace gsd {

namespace {

using Vec2 = Eigen::Vector2d;

/// The neighbours of every point (not the point itself, nor copies of it), nearest first.
struct Neighborhoods {
    int k = 0;
    std::vector<std::uint32_t> index;  ///< k per point; UINT32_MAX pads points with fewer
    std::uint32_t at(std::size_t i, int j) const { return index[i * std::size_t(k) + std::size_t(j)]; }
};

Neighborhoods find_neighbors(const KdTree& tree, int k) {
    const Points& p = tree.points();
    Neighborhoods n;
    n.k = k;
    n.index.assign(std::size_t(p.rows()) * std::size_t(k), UINT32_MAX);
    // In Morton order: consecutive searches walk the same tree nodes (the cloud's own order may
    // be random).
    const std::vector<std::uint32_t> order = spatial::morton_order(p);
#pragma omp parallel
    {
        std::vector<Neighbor> found;
#pragma omp for schedule(static)
        for (Eigen::Index o = 0; o < p.rows(); ++o) {
            const auto i = Eigen::Index(order[std::size_t(o)]);
            // A few extra in case copies of the point take the first places.
            tree.knn(p.row(i).transpose(), std::size_t(k) + 4, found);
            const double reach = found.empty() ? 0 : found.back().distance;
            int m = 0;
            for (const Neighbor& f : found) {
                if (m == k) break;
                if (Eigen::Index(f.index) == i || f.distance <= 1e-9 * reach) continue;
                n.index[std::size_t(i) * std::size_t(k) + std::size_t(m++)] = f.index;
            }
        }
    }
    return n;
}

/// The unit normal of the plane that fits a point and its neighbours best (the covariance's
/// eigenvector of least eigenvalue); sign arbitrary.
Eigen::Vector3d fitted_normal(const Points& p, const Neighborhoods& n, std::size_t i) {
    Eigen::Vector3d mean = p.row(Eigen::Index(i)).transpose();
    int count = 1;
    for (int j = 0; j < n.k && n.at(i, j) != UINT32_MAX; ++j, ++count) mean += p.row(n.at(i, j)).transpose();
    mean /= count;
    Eigen::Vector3d d = p.row(Eigen::Index(i)).transpose() - mean;
    Eigen::Matrix3d C = d * d.transpose();
    for (int j = 0; j < n.k && n.at(i, j) != UINT32_MAX; ++j) {
        d = p.row(n.at(i, j)).transpose() - mean;
        C += d * d.transpose();
    }
    Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(C);
    return eig.eigenvectors().col(0).normalized();
}

/// The connected pieces of the neighbour graph (symmetrized), each as its list of points.
std::vector<std::vector<std::uint32_t>> pieces(const std::vector<std::vector<std::uint32_t>>& adjacent) {
    std::vector<std::vector<std::uint32_t>> out;
    std::vector<std::uint8_t> seen(adjacent.size(), 0);
    for (std::size_t s = 0; s < adjacent.size(); ++s) {
        if (seen[s]) continue;
        std::vector<std::uint32_t> piece{std::uint32_t(s)};
        seen[s] = 1;
        for (std::size_t k = 0; k < piece.size(); ++k)
            for (std::uint32_t b : adjacent[piece[k]])
                if (!seen[b]) seen[b] = 1, piece.push_back(b);
        out.push_back(std::move(piece));
    }
    return out;
}

/// The point of a piece to start orienting from, with its normal turned to face away from the
/// piece's centroid (outward on a closed surface). A flat piece (its thinnest extent under a
/// tenth of its next: a plane, a noisy plane) has no outward; there the seed faces the
/// positive side of the axis the piece's own normal is closest to.
std::uint32_t oriented_seed(const Points& p, const std::vector<std::uint32_t>& piece, Points& normals) {
    Eigen::Vector3d centroid = Eigen::Vector3d::Zero();
    for (std::uint32_t i : piece) centroid += p.row(i).transpose();
    centroid /= double(piece.size());
    Eigen::Matrix3d C = Eigen::Matrix3d::Zero();
    std::uint32_t seed = piece[0];
    double far = -1;
    for (std::uint32_t i : piece) {
        const Eigen::Vector3d d = p.row(i).transpose() - centroid;
        C += d * d.transpose();
        if (d.squaredNorm() > far) far = d.squaredNorm(), seed = i;
    }
    const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(C);
    Eigen::Vector3d facing = p.row(seed).transpose() - centroid;
    if (eig.eigenvalues()[0] < 1e-2 * eig.eigenvalues()[1]) {
        facing = eig.eigenvectors().col(0);
        Eigen::Index axis;
        facing.cwiseAbs().maxCoeff(&axis);
        if (facing[axis] < 0) facing = -facing;
    }
    if (normals.row(seed).dot(facing) < 0) normals.row(seed) *= -1;
    return seed;
}

/// Flips normals so that neighbours agree (Hoppe et al. 1992): a minimum spanning tree of the
/// neighbour graph under the cost 1 − |n_i·n_j| is grown from one seed per connected piece
/// (oriented_seed), so the sign is passed along the smoothest paths and never across a sharp
/// fold when a gentler way round exists. With `reference` normals (the input's, perhaps noisy
/// or partly flipped) each piece then takes the sign most of them agree with.
void orient_normals(const Points& p, const Neighborhoods& n, Points& normals, const Points& reference) {
    const std::size_t N = std::size_t(p.rows());
    std::vector<std::vector<std::uint32_t>> adjacent(N);
    for (std::size_t i = 0; i < N; ++i)
        for (int j = 0; j < n.k && n.at(i, j) != UINT32_MAX; ++j) {
            adjacent[i].push_back(n.at(i, j));
            adjacent[n.at(i, j)].push_back(std::uint32_t(i));
        }
    std::vector<std::uint8_t> done(N, 0);
    struct Step {
        double cost;
        std::uint32_t to, from;
        bool operator>(const Step& o) const { return cost > o.cost; }
    };
    std::priority_queue<Step, std::vector<Step>, std::greater<Step>> frontier;
    for (const std::vector<std::uint32_t>& piece : pieces(adjacent)) {
        const std::uint32_t seed = oriented_seed(p, piece, normals);
        frontier.push({0, seed, seed});
        while (!frontier.empty()) {
            const Step s = frontier.top();
            frontier.pop();
            if (done[s.to]) continue;
            done[s.to] = 1;
            if (normals.row(s.to).dot(normals.row(s.from)) < 0) normals.row(s.to) *= -1;
            for (std::uint32_t b : adjacent[s.to])
                if (!done[b]) frontier.push({1 - std::abs(normals.row(s.to).dot(normals.row(b))), b, s.to});
        }
        if (reference.rows() == 0) continue;
        double agree = 0;
        for (std::uint32_t i : piece) agree += normals.row(i).dot(reference.row(i)) >= 0 ? 1 : -1;
        if (agree < 0)
            for (std::uint32_t i : piece) normals.row(i) *= -1;
    }
}

/// Replaces each (oriented) normal by the mean of its own and its neighbours' (normalized):
/// noise of the order of the spacing tilts single fits enough that neighbouring fans, each in
/// its own tangent plane, stop agreeing; the mean over ~30 fits tilts √30 times less, and on a
/// smooth surface sampled finely enough it is the normal at the point.
void smooth_normals(const Neighborhoods& n, Points& normals) {
    const Points fits = normals;
#pragma omp parallel for schedule(static)
    for (Eigen::Index i = 0; i < normals.rows(); ++i) {
        Eigen::Vector3d sum = fits.row(i).transpose();
        for (int j = 0; j < n.k && n.at(std::size_t(i), j) != UINT32_MAX; ++j) sum += fits.row(n.at(std::size_t(i), j)).transpose();
        if (sum.norm() > 1e-12) normals.row(i) = sum.normalized().transpose();
    }
}

/// The Voronoi cell of the origin among points q_j of the plane, as a convex polygon whose
/// edges remember which q_j's bisector they lie on (−1: the bounding square). Built by
/// clipping the square with one half-plane per point, nearest first.
///
/// Four (or more) cocircular points — every square of a grid, common in scans — leave the
/// Delaunay triangulation a free choice of diagonal, and each point's fan must make the same
/// one or the fans disagree everywhere. So a bisector that only touches the cell at a vertex
/// (the cocircular case, to rounding) is decided by a rule every fan applies alike: of the two
/// diagonals, the one holding the smallest point id. `ids[j]` is q_j's id, `center` the origin's.
/// "Only touches" is to within kCocircular × |q|² (the vertex within kCocircular·|q| of the
/// bisector): each fan sees its neighbours projected to its own tangent plane, which bends a
/// grid square of a surface curved on the scale of a few spacings by a few percent.
class VoronoiCell {
public:
    static constexpr double kCocircular = 1e-9;

    VoronoiCell(double half_size, const std::vector<std::uint32_t>& ids, std::uint32_t center) : ids_(ids), center_(center) {
        const double r = half_size;
        v_ = {{-r, -r}, {r, -r}, {r, r}, {-r, r}};
        label_ = {-1, -1, -1, -1};
    }

    /// Keeps the part of the cell nearer the origin than q (label: q's index).
    void clip(const Vec2& q, int label) {
        const double q2 = q.squaredNorm();
        const std::size_t m = v_.size();
        double reach = 0;
        for (const Vec2& v : v_) reach = std::max(reach, v.squaredNorm());
        if (q2 > 4 * reach) return;  // the bisector misses the cell
        d_.resize(m);
        for (std::size_t a = 0; a < m; ++a) d_[a] = v_[a].dot(q) - 0.5 * q2;
        // A near tie (cocircular to within the tangent-plane projection's distortion): the rule.
        const double tie = kCocircular * q2;
        std::size_t near = m, inside = 0;
        for (std::size_t a = 0; a < m; ++a) {
            if (std::abs(d_[a]) <= tie) near = near == m ? a : m + 1;
            inside += d_[a] < -tie;
        }
        if (near < m && inside == m - 1) {
            if (diagonal_wins(label, label_[(near + m - 1) % m], label_[near])) {
                v_.insert(v_.begin() + std::ptrdiff_t(near), v_[near]);  // a zero-length edge for q
                label_.insert(label_.begin() + std::ptrdiff_t(near), label);
            }
            return;
        }
        const double eps = 1e-10 * q2;
        out_v_.clear();
        out_label_.clear();
        for (std::size_t a = 0; a < m; ++a) {
            const Vec2& va = v_[a];
            const Vec2& vb = v_[(a + 1) % m];
            const double da = d_[a], db = d_[(a + 1) % m];
            if (da <= eps) {
                if (db <= eps) {
                    push(va, label_[a]);
                } else if (da >= -eps) {
                    push(va, label);  // the cut starts at va itself: no zero-length piece
                } else {
                    push(va, label_[a]);
                    push(va + (vb - va) * (da / (da - db)), label);
                }
            } else if (db < -eps) {
                push(va + (vb - va) * (da / (da - db)), label_[a]);
            }
        }
        if (out_v_.size() >= 3) {
            v_.swap(out_v_);
            label_.swap(out_label_);
        }
    }

    /// Labels of the cell's edges counter-clockwise: the Delaunay neighbours of the origin in
    /// angular order, with −1 where the cell is open (the origin is on the hull).
    const std::vector<int>& labels() const { return label_; }

private:
    /// Whether the diagonal origin–q is the one the cocircular rule keeps over before–after.
    bool diagonal_wins(int q, int before, int after) const {
        if (before < 0 || after < 0) return false;
        const std::uint32_t a = std::min(center_, ids_[std::size_t(q)]);
        const std::uint32_t b = std::min(ids_[std::size_t(before)], ids_[std::size_t(after)]);
        return a < b;
    }
    void push(const Vec2& v, int label) {
        out_v_.push_back(v);
        out_label_.push_back(label);
    }
    const std::vector<std::uint32_t>& ids_;
    std::uint32_t center_;
    std::vector<Vec2> v_, out_v_;
    std::vector<int> label_, out_label_;
    std::vector<double> d_;
};

using Triangle = std::array<std::uint32_t, 3>;

/// The triangles at point i of the Delaunay triangulation of i and its neighbours projected to
/// i's tangent plane, counter-clockwise seen from the normal's side.
void local_fan(const Points& p, const Neighborhoods& n, const Points& normals, std::size_t i,
               std::vector<Triangle>& out) {
    const Eigen::Vector3d c = p.row(Eigen::Index(i)).transpose();
    const Eigen::Vector3d nrm = normals.row(Eigen::Index(i)).transpose();
    const Eigen::Vector3d u = nrm.unitOrthogonal();
    const Eigen::Vector3d w = nrm.cross(u);  // (u, w, n) right-handed: counter-clockwise seen from n
    double reach = 0;
    std::vector<Vec2> q;
    std::vector<std::uint32_t> ids;
    for (int j = 0; j < n.k && n.at(i, j) != UINT32_MAX; ++j) {
        const Eigen::Vector3d d = p.row(n.at(i, j)).transpose() - c;
        q.emplace_back(d.dot(u), d.dot(w));
        ids.push_back(n.at(i, j));
        reach = std::max(reach, d.norm());
    }
    if (q.size() < 2 || reach <= 0) return;
    VoronoiCell cell(4 * reach, ids, std::uint32_t(i));
    for (std::size_t j = 0; j < q.size(); ++j)
        // A neighbour straight above or below the point (another sheet) has no bisector here.
        if (q[j].norm() > 1e-6 * reach) cell.clip(q[j], int(j));
    const std::vector<int>& L = cell.labels();
    for (std::size_t a = 0; a < L.size(); ++a) {
        const int before = L[(a + L.size() - 1) % L.size()], after = L[a];
        if (before >= 0 && after >= 0 && before != after)
            out.push_back({std::uint32_t(i), ids[std::size_t(before)], ids[std::size_t(after)]});
    }
}

/// Counts of each triangle over all fans, keyed by its sorted corners, with one of its
/// orientations (the fans of one connected piece agree on orientation).
struct TriangleSupport {
    std::array<std::uint32_t, 3> key;
    Triangle oriented;
    int count;
};

std::array<std::uint32_t, 3> sorted(Triangle t) {
    std::sort(t.begin(), t.end());
    return t;
}

std::vector<TriangleSupport> support(const std::vector<std::vector<Triangle>>& fans) {
    std::vector<TriangleSupport> all;
    for (const auto& fan : fans)
        for (const Triangle& t : fan) all.push_back({sorted(t), t, 1});
    std::sort(all.begin(), all.end(), [](const TriangleSupport& a, const TriangleSupport& b) { return a.key < b.key; });
    std::vector<TriangleSupport> out;
    for (const TriangleSupport& t : all)
        if (!out.empty() && out.back().key == t.key) ++out.back().count;
        else out.push_back(t);
    return out;
}

/// Directed edges a → b, as one 64-bit key each.
class HalfedgeSet {
public:
    bool has(std::uint32_t a, std::uint32_t b) const { return set_.count(key(a, b)) > 0; }
    bool has_either(std::uint32_t a, std::uint32_t b) const { return has(a, b) || has(b, a); }
    void add(std::uint32_t a, std::uint32_t b) { set_.insert(key(a, b)); }
    void remove(std::uint32_t a, std::uint32_t b) { set_.erase(key(a, b)); }
    void add(const Triangle& t) {
        for (int k = 0; k < 3; ++k) add(t[std::size_t(k)], t[std::size_t((k + 1) % 3)]);
    }
    template <class F>
    void for_each(F&& f) const {
        for (std::uint64_t k : set_) f(std::uint32_t(k >> 32), std::uint32_t(k));
    }

private:
    static std::uint64_t key(std::uint32_t a, std::uint32_t b) { return std::uint64_t(a) << 32 | b; }
    std::unordered_set<std::uint64_t> set_;
};

/// How many fans proposed a triangle (0 for none), looked up in the candidates sorted by key.
int votes_for(const std::vector<TriangleSupport>& by_key, const std::array<std::uint32_t, 3>& key) {
    const auto it = std::lower_bound(by_key.begin(), by_key.end(), key,
                                     [](const TriangleSupport& t, const std::array<std::uint32_t, 3>& k) { return t.key < k; });
    return it != by_key.end() && it->key == key ? it->count : 0;
}

/// The wedge each accepted triangle takes around each of its corners, as an angle interval in
/// that corner's tangent plane. A triangle whose wedge would overlap one already taken at some
/// corner is refused: that is how two fans' disagreeing triangles would otherwise stack up
/// around a point and give the surface a handle (seen on noisy clouds).
class Wedges {
public:
    Wedges(const Points& p, const Points& normals) : p_(p), n_(normals), taken_(std::size_t(p.rows())) {}

    bool fits(const Triangle& t) const {
        for (int k = 0; k < 3; ++k) {
            const Wedge w = wedge(t, k);
            for (const Wedge& o : taken_[t[std::size_t(k)]])
                if (overlap(w, o)) return false;
        }
        return true;
    }
    void take(const Triangle& t) {
        for (int k = 0; k < 3; ++k) taken_[t[std::size_t(k)]].push_back(wedge(t, k));
    }

private:
    struct Wedge {
        double start, width;  // counter-clockwise around the normal, radians
    };
    static constexpr double kTwoPi = 6.283185307179586;
    /// A sliver of overlap (rounding, nearly flat wedges) is allowed.
    static constexpr double kSlack = 1e-3;

    Wedge wedge(const Triangle& t, int k) const {
        const std::uint32_t v = t[std::size_t(k)], a = t[std::size_t((k + 1) % 3)], b = t[std::size_t((k + 2) % 3)];
        const Eigen::Vector3d n = n_.row(v).transpose();
        const Eigen::Vector3d u = n.unitOrthogonal(), w = n.cross(u);
        const Eigen::Vector3d da = (p_.row(a) - p_.row(v)).transpose(), db = (p_.row(b) - p_.row(v)).transpose();
        const double sa = std::atan2(da.dot(w), da.dot(u)), sb = std::atan2(db.dot(w), db.dot(u));
        return {sa, std::fmod(sb - sa + 2 * kTwoPi, kTwoPi)};
    }
    static bool overlap(const Wedge& x, const Wedge& y) {
        const double xy = std::fmod(y.start - x.start + 2 * kTwoPi, kTwoPi);  // y's start seen from x's
        const double yx = std::fmod(x.start - y.start + 2 * kTwoPi, kTwoPi);
        return xy < x.width - kSlack || yx < y.width - kSlack;
    }

    const Points& p_;
    const Points& n_;
    std::vector<std::vector<Wedge>> taken_;
};

/// Fills a hole (its loop of points, in the order that runs along the existing triangles'
/// edges reversed, so triangles made from consecutive points face the same side as their
/// neighbours) by clipping ears, each time the ear most fans proposed, then the one with the
/// shortest new edge; never adds an edge the mesh already has (that would make it nonmanifold).
/// Returns false, adding nothing, when it cannot.
bool fill_hole(std::vector<std::uint32_t> loop, const Points& p, const std::vector<TriangleSupport>& votes,
               HalfedgeSet& edges, Wedges& wedges, bool check_wedges, std::vector<Triangle>& out) {
    std::vector<Triangle> made;
    std::vector<std::pair<std::uint32_t, std::uint32_t>> added;  // new diagonals, marked while clipping
    auto undo = [&] {
        for (const auto& [a, b] : added) edges.remove(a, b);
        return false;
    };
    while (loop.size() > 3) {
        const std::size_t n = loop.size();
        std::size_t best = n;
        int best_votes = -1;
        double best_length = INFINITY;
        for (std::size_t k = 0; k < n; ++k) {
            const std::uint32_t a = loop[(k + n - 1) % n], b = loop[k], c = loop[(k + 1) % n];
            if (a == c || edges.has_either(a, c) || (check_wedges && !wedges.fits({a, b, c}))) continue;
            const int count = votes_for(votes, sorted({a, b, c}));
            const double length = (p.row(a) - p.row(c)).norm();
            if (count > best_votes || (count == best_votes && length < best_length))
                best = k, best_votes = count, best_length = length;
        }
        if (best == n) return undo();
        const std::uint32_t a = loop[(best + n - 1) % n], b = loop[best], c = loop[(best + 1) % n];
        made.push_back({a, b, c});
        edges.add(c, a);
        added.push_back({c, a});
        loop.erase(loop.begin() + std::ptrdiff_t(best));
    }
    if (loop[0] == loop[1] || loop[1] == loop[2] || loop[0] == loop[2] ||
        (check_wedges && !wedges.fits({loop[0], loop[1], loop[2]})))
        return undo();
    made.push_back({loop[0], loop[1], loop[2]});
    out.insert(out.end(), made.begin(), made.end());
    for (const Triangle& t : made) {
        edges.add(t);
        wedges.take(t);
    }
    return true;
}

/// A manifold, consistently oriented mesh from the fans: triangles taken greedily, those more
/// fans proposed first (three: all their corners agree), then the more compact, each only if
/// none of its edges already runs its way and its wedge at each corner overlaps none taken
/// there. Triangles only one fan proposed come last but still count: on a parametric grid of a
/// curved surface, every other square is split one way by two of its corners' fans and the
/// other way by the other two, so no triangle of it has more than one vote. The holes left are
/// filled when their loop has at most `max_hole` points; larger loops are the cloud's own
/// boundary and stay open.
std::vector<Triangle> agreed_triangulation(const Points& p, const Points& normals, const std::vector<std::vector<Triangle>>& fans,
                                           std::size_t max_hole) {
    const std::vector<TriangleSupport> votes = support(fans);  // sorted by key
    std::vector<TriangleSupport> candidates = votes;
    auto longest_side = [&](const TriangleSupport& t) {
        return std::max({(p.row(t.key[0]) - p.row(t.key[1])).squaredNorm(), (p.row(t.key[1]) - p.row(t.key[2])).squaredNorm(),
                         (p.row(t.key[2]) - p.row(t.key[0])).squaredNorm()});
    };
    std::stable_sort(candidates.begin(), candidates.end(), [&](const TriangleSupport& a, const TriangleSupport& b) {
        return a.count != b.count ? a.count > b.count : longest_side(a) < longest_side(b);
    });
    std::vector<Triangle> tris;
    HalfedgeSet edges;
    Wedges wedges(p, normals);
    for (const TriangleSupport& t : candidates) {
        bool taken = false;
        for (int k = 0; k < 3; ++k) taken |= edges.has(t.oriented[std::size_t(k)], t.oriented[std::size_t((k + 1) % 3)]);
        if (taken || !wedges.fits(t.oriented)) continue;
        tris.push_back(t.oriented);
        edges.add(t.oriented);
        wedges.take(t.oriented);
    }
    // Hole loops run along boundary halfedges reversed: a → b on a triangle, nothing b → a.
    std::map<std::uint32_t, std::vector<std::uint32_t>> hole_next;  // b → a for each boundary a → b
    edges.for_each([&](std::uint32_t a, std::uint32_t b) {
        if (!edges.has(b, a)) hole_next[b].push_back(a);
    });
    for (auto& [from, to] : hole_next) std::sort(to.begin(), to.end());  // the same walk whatever the hash order
    HalfedgeSet walked;
    std::vector<std::vector<std::uint32_t>> loops;
    for (const auto& [start, targets] : hole_next)
        for (std::uint32_t first : targets) {
            if (walked.has(start, first)) continue;
            std::vector<std::uint32_t> loop{start};
            walked.add(start, first);
            std::uint32_t at = first;
            bool closed = false;
            while (loop.size() <= max_hole) {
                if (at == start) {
                    closed = true;
                    break;
                }
                loop.push_back(at);
                const auto it = hole_next.find(at);
                std::uint32_t to = UINT32_MAX;
                if (it != hole_next.end())
                    for (std::uint32_t c : it->second)
                        if (!walked.has(at, c)) {
                            to = c;
                            break;
                        }
                if (to == UINT32_MAX) break;
                walked.add(at, to);
                at = to;
            }
            if (closed && loop.size() >= 3) loops.push_back(std::move(loop));
        }

    // A hole no ear fits without overlapping a wedge (noisy clouds: the tangent planes
    // disagree) is still filled: a small fold is better than a hole, which SWN and level sets
    // would read as boundary.
    for (const auto& loop : loops)
        if (!fill_hole(loop, p, votes, edges, wedges, true, tris)) fill_hole(loop, p, votes, edges, wedges, false, tris);

    return tris;
}

}  // namespace

CloudSurface cloud_surface(const Points& points, const Points& normals, const CloudSurfaceOptions& options,
                           const std::string& where) {
    if (options.neighbors < 3 || options.neighbors > 64)
        throw Error(where, "cloud surface: neighbors must be in [3, 64], got " + std::to_string(options.neighbors));
    if (points.rows() < 3) throw Error(where, "cloud surface: needs at least 3 points, got " + std::to_string(points.rows()));
    if (normals.rows() != 0 && normals.rows() != points.rows())
        throw Error(where, "cloud surface: " + std::to_string(normals.rows()) + " normals for " +
                               std::to_string(points.rows()) + " points");
    if (std::size_t(points.rows()) >= std::size_t(UINT32_MAX) / 256)
        throw Error(where, "cloud surface: too many points for the surface methods");
    check_coordinates(points, where, "point");

    const KdTree tree(points);
    const Neighborhoods n = find_neighbors(tree, options.neighbors);
    const std::size_t N = std::size_t(points.rows());
    Points fitted(points.rows(), 3);
#pragma omp parallel for schedule(static)
    for (Eigen::Index i = 0; i < points.rows(); ++i) fitted.row(i) = fitted_normal(points, n, std::size_t(i)).transpose();
    orient_normals(points, n, fitted, normals);
    smooth_normals(n, fitted);

    std::vector<std::vector<Triangle>> fans(N);
#pragma omp parallel for schedule(dynamic, 256)
    for (Eigen::Index i = 0; i < points.rows(); ++i) local_fan(points, n, fitted, std::size_t(i), fans[std::size_t(i)]);
    PolygonMesh mesh;
    mesh.vertices = points;
    std::size_t count = 0;
    for (const auto& f : fans) count += f.size();
    if (count == 0) throw Error(where, "cloud surface: the points span no surface (all on a line?)");
    mesh.indices.reserve(3 * count);
    mesh.offsets.reserve(count + 1);
    for (const auto& f : fans)
        for (const Triangle& t : f) mesh.add_face(t.data(), 3);
    PolygonMesh agreed;
    agreed.vertices = points;
    for (const Triangle& t : agreed_triangulation(points, fitted, fans, kMaxFilledHole)) agreed.add_face(t.data(), 3);
    return CloudSurface{SurfaceMesh(std::move(mesh), where), std::move(fitted), std::move(agreed)};
}

void require_cloud_points(const SurfaceSources& sources, const std::string& where) {
    auto check = [&](const SurfacePoint& p) {
        if (p.kind != SurfacePoint::Kind::Vertex)
            throw Error(where, "on a point cloud, curves and points name cloud points (`v i` records, or `l` lines of "
                               "point indices); `e` and `f` records name a mesh's edges and faces");
    };
    for (const SurfaceCurve& c : sources.curves)
        for (const SurfacePoint& p : c.nodes) check(p);
    for (const SurfacePoint& p : sources.points) check(p);
}

}  // namespace gsd
