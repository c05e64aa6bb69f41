// triangles.cpp — see triangles.hpp.
#include "sdf/triangles.hpp"

#include "core/disjoint_sets.hpp"

#include <Eigen/Geometry>

#include <algorithm>
#include <numeric>

namespace gsd::sdf {

namespace {

// Vertex ids after welding: vertices with equal coordinates (−0 and +0 alike) share the id of
// the first of them; returns how many were merged.
std::size_t weld(const Points& v, std::vector<std::uint32_t>& id) {
    const auto n = std::size_t(v.rows());
    std::vector<std::uint32_t> order(n);
    std::iota(order.begin(), order.end(), 0u);
    auto key = [&](std::uint32_t i) {
        return std::array<double, 3>{v(i, 0) + 0.0, v(i, 1) + 0.0, v(i, 2) + 0.0};
    };
    std::stable_sort(order.begin(), order.end(), [&](std::uint32_t a, std::uint32_t b) { return key(a) < key(b); });
    id.resize(n);
    std::size_t merged = 0;
    for (std::size_t k = 0; k < n; ++k) {
        const std::uint32_t i = order[k];
        if (k > 0 && key(order[k - 1]) == key(i)) {
            id[i] = id[order[k - 1]];
            ++merged;
        } else {
            id[i] = i;
        }
    }
    return merged;
}

// One directed edge of a triangle, keyed by its two vertices in increasing order.
struct EdgeUse {
    std::uint32_t lo, hi;
    std::uint32_t triangle;
    bool forward;  // the triangle runs lo → hi
};

// Each group of uses of one edge, as [begin, end) ranges into the sorted uses.
template <class Visit>
void for_each_edge(std::vector<EdgeUse>& uses, Visit visit) {
    std::sort(uses.begin(), uses.end(), [](const EdgeUse& a, const EdgeUse& b) {
        return a.lo != b.lo ? a.lo < b.lo : a.hi != b.hi ? a.hi < b.hi : a.triangle < b.triangle;
    });
    for (std::size_t i = 0; i < uses.size();) {
        std::size_t j = i + 1;
        while (j < uses.size() && uses[j].lo == uses[i].lo && uses[j].hi == uses[i].hi) ++j;
        visit(&uses[i], j - i);
        i = j;
    }
}

std::vector<EdgeUse> edge_uses(const Triangles& t) {  // duplicates left out
    std::vector<EdgeUse> uses;
    uses.reserve(3 * t.triangles.size());
    for (std::uint32_t f = 0; f < t.triangles.size(); ++f) {
        if (t.duplicate[f]) continue;
        for (int k = 0; k < 3; ++k) {
            const std::uint32_t a = t.triangles[f][std::size_t(k)], b = t.triangles[f][std::size_t((k + 1) % 3)];
            uses.push_back({std::min(a, b), std::max(a, b), f, a < b});
        }
    }
    return uses;
}

// Triangles over the same three vertices as an earlier one (either orientation).
std::vector<std::uint8_t> find_duplicates(const std::vector<Triangle>& tri, std::size_t& count) {
    std::vector<Triangle> key(tri.size());
    for (std::size_t f = 0; f < tri.size(); ++f) {
        key[f] = tri[f];
        std::sort(key[f].begin(), key[f].end());
    }
    std::vector<std::uint32_t> order(tri.size());
    std::iota(order.begin(), order.end(), 0u);
    std::stable_sort(order.begin(), order.end(), [&](std::uint32_t a, std::uint32_t b) { return key[a] < key[b]; });
    std::vector<std::uint8_t> duplicate(tri.size(), 0);
    count = 0;
    for (std::size_t k = 1; k < order.size(); ++k)
        if (key[order[k]] == key[order[k - 1]]) {
            duplicate[order[k]] = 1;  // stable: the earlier triangle is kept
            ++count;
        }
    return duplicate;
}

bool boxes_overlap(const Box& a, const Box& b) {
    return (a.lo.array() <= b.hi.array()).all() && (b.lo.array() <= a.hi.array()).all();
}

// Components through manifold edges (two uses), and whether two of them have overlapping boxes
// (checked pairwise up to a few hundred components; more count as overlapping).
void count_components(Triangles& t, std::vector<EdgeUse> uses) {
    detail::DisjointSets sets(t.triangles.size());
    for_each_edge(uses, [&](const EdgeUse* e, std::size_t n) {
        if (n == 2) sets.join(e[0].triangle, e[1].triangle);
    });
    std::vector<std::int64_t> index(t.triangles.size(), -1);
    std::vector<Box> boxes;
    for (std::uint32_t f = 0; f < t.triangles.size(); ++f) {
        if (t.duplicate[f]) continue;
        std::int64_t& c = index[sets.find(f)];
        if (c < 0) {
            c = std::int64_t(boxes.size());
            const Eigen::Vector3d p = t.vertices.row(t.triangles[f][0]);
            boxes.push_back({p, p});
        }
        for (std::uint32_t v : t.triangles[f]) {
            const Eigen::Vector3d p = t.vertices.row(v);
            boxes[std::size_t(c)].lo = boxes[std::size_t(c)].lo.cwiseMin(p);
            boxes[std::size_t(c)].hi = boxes[std::size_t(c)].hi.cwiseMax(p);
        }
    }
    t.report.components = boxes.size();
    constexpr std::size_t kPairwise = 512;
    if (boxes.size() > kPairwise) {
        t.report.overlapping_components = true;
        return;
    }
    for (std::size_t i = 0; i < boxes.size() && !t.report.overlapping_components; ++i)
        for (std::size_t j = i + 1; j < boxes.size(); ++j)
            if (boxes_overlap(boxes[i], boxes[j])) {
                t.report.overlapping_components = true;
                break;
            }
}

double area(const Triangles& t, std::uint32_t f) {
    const Eigen::Vector3d a = t.vertices.row(t.triangles[f][0]), b = t.vertices.row(t.triangles[f][1]),
                          c = t.vertices.row(t.triangles[f][2]);
    return 0.5 * (b - a).cross(c - a).norm();
}

std::string count_of(std::size_t n, const char* what) { return std::to_string(n) + " " + what; }

}  // namespace

std::string TriangleReport::summary() const {
    std::string s = count_of(triangles - degenerate, "triangles");
    if (degenerate) s += ", " + count_of(degenerate, "degenerate (left out)");
    if (welded_vertices) s += ", " + count_of(welded_vertices, "vertices at another's position (welded)");
    if (duplicates) s += ", " + count_of(duplicates, "duplicated triangles");
    s += ", " + count_of(boundary_edges, "boundary edges") + ", " + count_of(nonmanifold_edges, "nonmanifold edges") + ", " +
         count_of(misoriented_edges, "edges between triangles of opposite orientation") + ", " +
         count_of(components, components == 1 ? "component" : "components");
    if (overlapping_components) s += " (some overlapping)";
    return s;
}

Triangles check_triangles(const PolygonMesh& mesh) {
    Triangles t;
    t.vertices = mesh.vertices;
    std::vector<std::uint32_t> id;
    t.report.welded_vertices = weld(mesh.vertices, id);
    std::uint32_t fanned = 0;
    for_each_triangle(mesh, [&](std::size_t, std::uint32_t a, std::uint32_t b, std::uint32_t c) {
        const std::uint32_t index = fanned++;
        const Eigen::Vector3d pa = mesh.vertices.row(a), pb = mesh.vertices.row(b), pc = mesh.vertices.row(c);
        if (!((pb - pa).cross(pc - pa).norm() > 0)) return;  // as OrientedElements::from_mesh
        t.triangles.push_back({id[a], id[b], id[c]});
        t.source.push_back(index);
    });
    t.report.triangles = fanned;
    t.report.degenerate = fanned - t.triangles.size();
    if (t.triangles.empty()) throw Error("mesh", "all faces are degenerate (zero area)");
    t.duplicate = find_duplicates(t.triangles, t.report.duplicates);
    std::vector<EdgeUse> uses = edge_uses(t);
    count_components(t, uses);  // sorts its own copy
    for_each_edge(uses, [&](const EdgeUse* e, std::size_t n) {
        if (n == 1) ++t.report.boundary_edges;
        else if (n > 2) ++t.report.nonmanifold_edges;
        else if (e[0].forward == e[1].forward) ++t.report.misoriented_edges;
    });
    return t;
}

std::size_t repair_orientation(Triangles& t) {
    const std::vector<std::uint8_t>& duplicate = t.duplicate;  // found by check_triangles
    // Neighbours across manifold edges, each with whether the two run along it the same way
    // (then one of them must turn).
    std::vector<EdgeUse> uses = edge_uses(t);
    const std::size_t F = t.triangles.size();
    std::vector<std::uint32_t> begin(F + 1, 0);
    std::vector<std::pair<std::uint32_t, std::uint32_t>> pairs;  // (triangle, neighbour·2 + same)
    for_each_edge(uses, [&](const EdgeUse* e, std::size_t n) {
        if (n != 2) return;
        const std::uint32_t same = e[0].forward == e[1].forward;
        pairs.push_back({e[0].triangle, 2 * e[1].triangle + same});
        pairs.push_back({e[1].triangle, 2 * e[0].triangle + same});
    });
    std::sort(pairs.begin(), pairs.end());
    for (const auto& p : pairs) ++begin[p.first + 1];
    std::partial_sum(begin.begin(), begin.end(), begin.begin());
    // Breadth first from each unvisited triangle; flip[g] = flip[f] xor same. Then each
    // component keeps the orientation of the larger part of its area.
    std::vector<std::int8_t> flip(F, -1);
    std::vector<std::uint32_t> queue;
    std::size_t turned = 0;
    for (std::uint32_t f0 = 0; f0 < F; ++f0) {
        if (duplicate[f0] || flip[f0] >= 0) continue;
        queue.assign(1, f0);
        flip[f0] = 0;
        double kept = 0, flipped = 0;
        for (std::size_t q = 0; q < queue.size(); ++q) {
            const std::uint32_t f = queue[q];
            (flip[f] ? flipped : kept) += area(t, f);
            for (std::uint32_t k = begin[f]; k < begin[f + 1]; ++k) {
                const std::uint32_t g = pairs[k].second / 2, same = pairs[k].second % 2;
                if (flip[g] >= 0) continue;
                flip[g] = std::int8_t(flip[f] ^ std::int8_t(same));
                queue.push_back(g);
            }
        }
        const std::int8_t turn = flipped > kept ? 0 : 1;  // the triangles to turn have flip == turn
        for (std::uint32_t f : queue)
            if (flip[f] == turn) {
                std::swap(t.triangles[f][1], t.triangles[f][2]);
                ++turned;
            }
    }
    std::size_t kept = 0;
    for (std::size_t f = 0; f < F; ++f)
        if (!duplicate[f]) {
            t.triangles[kept] = t.triangles[f];
            t.source[kept] = t.source[f];
            ++kept;
        }
    t.triangles.resize(kept);
    t.source.resize(kept);
    t.duplicate.assign(kept, 0);
    return turned;
}

}  // namespace gsd::sdf
