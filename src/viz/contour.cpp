// Iso-surface extraction by marching tetrahedra.
//
// Each grid cube is split into the six Kuhn (Freudenthal) tetrahedra that share the cube's main
// diagonal (0,0,0)–(1,1,1). The split is the same translated copy in every cube, so the face
// diagonals of neighboring cubes agree and the tetrahedra tile the grid without gaps. Inside a
// tetrahedron the linear interpolant's level set is a single triangle or quad, with no
// ambiguous cases: the result is closed and manifold wherever the level set is closed inside
// the grid. (Lorensen's 15-case cube table is ambiguous on faces with alternating signs and
// cracks there; this needs no decider.)
//
// Every surface vertex lies on a grid edge (cube edges, face diagonals or the cube diagonal) and
// is shared through a map keyed by the edge's lower node and its direction. Edges always run
// from a node to a node with larger-or-equal indices, so the map only needs the two node slabs
// (i and i+1) touched by the current layer of cubes.
//
// Values exactly equal to iso count as "above". A vertex that lands exactly on a node (value ==
// iso, or an interpolation that rounds onto the node) is welded to one vertex per node; the
// triangles that this collapses (repeated vertices, or a pair of opposite copies where a level
// set only touches a layer of nodes) are removed afterwards.
#include <gsd/viz.hpp>

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <sstream>

namespace gsd {
namespace {

constexpr std::uint32_t kNoVertex = std::numeric_limits<std::uint32_t>::max();

// A cube corner is coded by its offset bits: di | dj << 1 | dk << 2.
constexpr int corner_di(int c) { return c & 1; }
constexpr int corner_dj(int c) { return (c >> 1) & 1; }
constexpr int corner_dk(int c) { return (c >> 2) & 1; }

// The Kuhn tetrahedron for axis order (a, b, c) walks 0 → e_a → e_a+e_b → (1,1,1). Its
// orientation (sign of det(e_a, e_b, e_c)) is the parity of (a, b, c); grid spacings are
// positive, so this holds in world coordinates too.
struct KuhnTet {
    std::array<int, 4> corner;
    bool positive;
};
constexpr std::array<KuhnTet, 6> kTets{{
    {{0, 1, 3, 7}, true},   // x, y, z
    {{0, 1, 5, 7}, false},  // x, z, y
    {{0, 2, 3, 7}, false},  // y, x, z
    {{0, 2, 6, 7}, true},   // y, z, x
    {{0, 4, 5, 7}, true},   // z, x, y
    {{0, 4, 6, 7}, false},  // z, y, x
}};

// Parity of a permutation of four distinct small integers (true: even).
bool is_even_permutation(const std::array<int, 4>& p) {
    int inversions = 0;
    for (int a = 0; a < 4; ++a)
        for (int b = a + 1; b < 4; ++b) inversions += p[a] > p[b];
    return inversions % 2 == 0;
}

// One corner of the tetrahedron being processed.
struct TetCorner {
    int i, j, k;  // node indices
    int code;     // cube corner code (edges run from a smaller to a larger superset code)
    double value;
};

class TetContourer {
public:
    TetContourer(const GridSpec& grid, const std::vector<float>& values, double iso)
        : grid_(grid), values_(values), iso_(iso), slab_size_(std::size_t(grid.ny) * grid.nz) {
        for (int i = 0; i < grid.nx; ++i) xs_.push_back(grid.node(i, 0, 0).x());
        for (int j = 0; j < grid.ny; ++j) ys_.push_back(grid.node(0, j, 0).y());
        for (int k = 0; k < grid.nz; ++k) zs_.push_back(grid.node(0, 0, k).z());
        for (int s = 0; s < 2; ++s) {
            edge_vertex_[s].assign(slab_size_ * 8, kNoVertex);
            node_vertex_[s].assign(slab_size_, kNoVertex);
        }
    }

    void run() {
        for (int i = 0; i + 1 < grid_.nx; ++i) {
            if (i > 0) forget_slab(i + 1);  // its storage last held slab i-1, which is done
            for (int j = 0; j + 1 < grid_.ny; ++j)
                for (int k = 0; k + 1 < grid_.nz; ++k) cube(i, j, k);
        }
        if (welded_) remove_collapsed_triangles();
    }

    PolygonMesh take_mesh() {
        remove_unused_vertices();
        PolygonMesh mesh;
        const auto n = static_cast<Eigen::Index>(positions_.size() / 3);
        mesh.vertices = Eigen::Map<const Points>(positions_.data(), n, 3);
        mesh.indices.reserve(triangles_.size() * 3);
        mesh.offsets.reserve(triangles_.size() + 1);
        for (const auto& t : triangles_) mesh.add_face(t.data(), 3);
        return mesh;
    }

private:
    using Triangle = std::array<std::uint32_t, 3>;

    std::size_t node_index(int i, int j, int k) const {
        return (std::size_t(i) * grid_.ny + j) * grid_.nz + k;
    }
    bool above(double v) const { return v >= iso_; }

    void forget_slab(int i) {
        std::fill(edge_vertex_[i & 1].begin(), edge_vertex_[i & 1].end(), kNoVertex);
        std::fill(node_vertex_[i & 1].begin(), node_vertex_[i & 1].end(), kNoVertex);
    }

    void cube(int i, int j, int k) {
        std::array<double, 8> v;
        int above_count = 0;
        for (int c = 0; c < 8; ++c) {
            v[c] = values_[node_index(i + corner_di(c), j + corner_dj(c), k + corner_dk(c))];
            above_count += above(v[c]);
        }
        if (above_count == 0 || above_count == 8) return;  // the level set misses this cube
        for (const KuhnTet& tet : kTets) {
            std::array<TetCorner, 4> corners;
            for (int n = 0; n < 4; ++n) {
                const int c = tet.corner[n];
                corners[n] = {i + corner_di(c), j + corner_dj(c), k + corner_dk(c), c, v[c]};
            }
            tetrahedron(corners, tet.positive);
        }
    }

    // Emits the piece of the level set inside one tetrahedron. The corners are split into
    // below (B) and above (A); writing the tetrahedron as an even permutation (b…, a…) of a
    // positively oriented one fixes the winding that puts the normal on the A side.
    void tetrahedron(const std::array<TetCorner, 4>& c, bool positive) {
        std::array<int, 4> below{}, abv{};
        int nb = 0, na = 0;
        for (int n = 0; n < 4; ++n) (above(c[n].value) ? abv[na++] : below[nb++]) = n;
        if (nb == 0 || na == 0) return;

        auto e = [&](int p, int q) { return edge_vertex(c[p], c[q]); };
        if (nb == 1) {
            int b = below[0], a0 = abv[0], a1 = abv[1], a2 = abv[2];
            if (is_even_permutation({b, a0, a1, a2}) != positive) std::swap(a1, a2);
            add_triangle({e(b, a0), e(b, a1), e(b, a2)});
        } else if (nb == 3) {
            int a = abv[0], b0 = below[0], b1 = below[1], b2 = below[2];
            // Same face as above, but the normal must point toward the single above corner.
            if (is_even_permutation({a, b0, b1, b2}) == positive) std::swap(b1, b2);
            add_triangle({e(a, b0), e(a, b1), e(a, b2)});
        } else {
            int b0 = below[0], b1 = below[1], a0 = abv[0], a1 = abv[1];
            if (is_even_permutation({b0, b1, a0, a1}) != positive) std::swap(a0, a1);
            add_quad({e(b0, a0), e(b0, a1), e(b1, a1), e(b1, a0)});
        }
    }

    // Splits the quad along its shorter diagonal: either split is consistent with the
    // neighbors (the diagonal is inside the tetrahedron), the shorter one gives fatter triangles.
    void add_quad(const std::array<std::uint32_t, 4>& q) {
        if (distance2(q[0], q[2]) <= distance2(q[1], q[3])) {
            add_triangle({q[0], q[1], q[2]});
            add_triangle({q[0], q[2], q[3]});
        } else {
            add_triangle({q[0], q[1], q[3]});
            add_triangle({q[1], q[2], q[3]});
        }
    }

    void add_triangle(const Triangle& t) { triangles_.push_back(t); }

    double distance2(std::uint32_t a, std::uint32_t b) const {
        double s = 0;
        for (int d = 0; d < 3; ++d) {
            const double diff = positions_[3 * a + d] - positions_[3 * b + d];
            s += diff * diff;
        }
        return s;
    }

    Eigen::Vector3d position(const TetCorner& n) const { return {xs_[n.i], ys_[n.j], zs_[n.k]}; }

    // The vertex where the level set crosses the edge between two corners of one tetrahedron
    // (one below, one above), created on first use. `p` and `q` may come in either order; the
    // key is the corner with the smaller code plus the edge direction.
    std::uint32_t edge_vertex(const TetCorner& p, const TetCorner& q) {
        const TetCorner& from = p.code < q.code ? p : q;
        const TetCorner& to = p.code < q.code ? q : p;
        const int direction = from.code ^ to.code;  // 1..7: which axes the edge advances
        std::uint32_t& slot =
            edge_vertex_[from.i & 1][(std::size_t(from.j) * grid_.nz + from.k) * 8 + direction];
        if (slot == kNoVertex) slot = new_edge_vertex(p, q);
        return slot;
    }

    std::uint32_t new_edge_vertex(const TetCorner& p, const TetCorner& q) {
        const TetCorner& lo = above(p.value) ? q : p;
        const TetCorner& hi = above(p.value) ? p : q;
        const double t = (iso_ - lo.value) / (hi.value - lo.value);  // lo < iso <= hi
        if (t >= 1) return node_vertex(hi);
        if (t <= 0) return node_vertex(lo);
        const Eigen::Vector3d a = position(lo), b = position(hi);
        const Eigen::Vector3d x = a + t * (b - a);
        // An interpolation that rounds onto a node would duplicate that point: weld instead.
        if (x == b) return node_vertex(hi);
        if (x == a) return node_vertex(lo);
        return push_vertex(x);
    }

    std::uint32_t node_vertex(const TetCorner& n) {
        std::uint32_t& slot = node_vertex_[n.i & 1][std::size_t(n.j) * grid_.nz + n.k];
        if (slot == kNoVertex) {
            slot = push_vertex(position(n));
            welded_ = true;
        }
        return slot;
    }

    std::uint32_t push_vertex(const Eigen::Vector3d& x) {
        if (positions_.size() / 3 >= kNoVertex)
            throw Error("contour", "iso-surface has more than 2^32 vertices");
        positions_.insert(positions_.end(), {x.x(), x.y(), x.z()});
        return static_cast<std::uint32_t>(positions_.size() / 3 - 1);
    }

    // After welding: drop triangles that collapsed to an edge or a point, and cancel pairs of
    // copies with opposite winding (both sides of a sheet of nodes with value == iso where the
    // level set only touches them). What stays is the surface with the collapsed parts removed.
    void remove_collapsed_triangles() {
        std::erase_if(triangles_, [](const Triangle& t) {
            return t[0] == t[1] || t[1] == t[2] || t[0] == t[2];
        });
        struct Keyed {
            Triangle sorted;
            bool even;  // winding relative to the sorted order
            std::size_t index;
        };
        std::vector<Keyed> keyed;
        keyed.reserve(triangles_.size());
        for (std::size_t n = 0; n < triangles_.size(); ++n) {
            Triangle s = triangles_[n];
            std::sort(s.begin(), s.end());
            // A cyclic rotation keeps the winding: it is even iff the sorted first
            // vertex is followed by the sorted second one.
            const Triangle& t = triangles_[n];
            const int first = int(std::find(t.begin(), t.end(), s[0]) - t.begin());
            keyed.push_back({s, t[(first + 1) % 3] == s[1], n});
        }
        std::sort(keyed.begin(), keyed.end(), [](const Keyed& a, const Keyed& b) {
            return a.sorted != b.sorted ? a.sorted < b.sorted : a.index < b.index;
        });
        std::vector<bool> drop(triangles_.size(), false);
        for (std::size_t g = 0; g < keyed.size();) {
            std::size_t end = g;
            while (end < keyed.size() && keyed[end].sorted == keyed[g].sorted) ++end;
            cancel_opposite_pairs(keyed.begin() + g, keyed.begin() + end, drop);
            g = end;
        }
        std::vector<Triangle> kept;
        kept.reserve(triangles_.size());
        for (std::size_t n = 0; n < triangles_.size(); ++n)
            if (!drop[n]) kept.push_back(triangles_[n]);
        triangles_ = std::move(kept);
    }

    template <class It>
    static void cancel_opposite_pairs(It first, It last, std::vector<bool>& drop) {
        std::vector<std::size_t> even, odd;
        for (It it = first; it != last; ++it) (it->even ? even : odd).push_back(it->index);
        const std::size_t pairs = std::min(even.size(), odd.size());
        for (std::size_t n = 0; n < pairs; ++n) drop[even[n]] = drop[odd[n]] = true;
    }

    void remove_unused_vertices() {
        if (!welded_) return;  // without welding every vertex belongs to some triangle
        std::vector<std::uint32_t> remap(positions_.size() / 3, kNoVertex);
        std::vector<double> kept;
        kept.reserve(positions_.size());
        for (auto& t : triangles_)
            for (auto& v : t) {
                if (remap[v] == kNoVertex) {
                    remap[v] = static_cast<std::uint32_t>(kept.size() / 3);
                    kept.insert(kept.end(), positions_.begin() + 3 * v, positions_.begin() + 3 * v + 3);
                }
                v = remap[v];
            }
        positions_ = std::move(kept);
    }

    const GridSpec& grid_;
    const std::vector<float>& values_;
    const double iso_;
    const std::size_t slab_size_;
    std::vector<double> xs_, ys_, zs_;                 // node coordinates per axis
    std::array<std::vector<std::uint32_t>, 2> edge_vertex_;  // per slab parity: (j, k, direction)
    std::array<std::vector<std::uint32_t>, 2> node_vertex_;  // per slab parity: (j, k) welds
    std::vector<double> positions_;
    std::vector<Triangle> triangles_;
    bool welded_ = false;
};

void check_contour_input(const GridSpec& grid, const std::vector<float>& values, double iso) {
    grid.validate();
    if (values.size() != grid.node_count()) {
        std::ostringstream s;
        s << "grid has " << grid.node_count() << " nodes but " << values.size() << " values were given";
        throw Error("values", s.str());
    }
    if (!std::isfinite(iso)) throw Error("iso", "iso value must be finite");
    for (std::size_t n = 0; n < values.size(); ++n)
        if (!std::isfinite(values[n])) {
            const std::size_t k = n % grid.nz, j = (n / grid.nz) % grid.ny, i = n / grid.nz / grid.ny;
            std::ostringstream s;
            s << "non-finite value at grid node (" << i << ", " << j << ", " << k << ")";
            throw Error("values", s.str());
        }
}

}  // namespace

PolygonMesh contour(const GridSpec& grid, const std::vector<float>& values, double iso) {
    check_contour_input(grid, values, iso);
    TetContourer contourer(grid, values, iso);
    contourer.run();
    return contourer.take_mesh();
}

}  // namespace gsd
