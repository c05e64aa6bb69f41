// Meshes for the surface methods' tests, benchmarks and demos: a flat square and an icosphere,
// whose exact geodesic distances are known, and a torus and a double torus (genus 1 and 2) for
// curves that bound nothing.
#include <gsd/shapes.hpp>
#include <gsd/viz.hpp>

#include <Eigen/Geometry>

#include <map>
#include <random>

namespace gsd::shapes {

PolygonMesh grid_mesh(int n, double jitter, bool random_diagonals, std::uint64_t seed, double half) {
    if (n < 1 || n > 8192) throw Error("grid_mesh", "n must be in 1..8192");
    if (!(jitter >= 0 && jitter < 0.5)) throw Error("grid_mesh", "jitter must be in [0, 0.5)");
    std::mt19937_64 rng(seed);
    std::uniform_real_distribution<double> u(-1, 1);
    const double cell = 2 * half / n;
    PolygonMesh m;
    m.vertices.resize(Eigen::Index((n + 1) * (n + 1)), 3);
    for (int j = 0; j <= n; ++j)
        for (int i = 0; i <= n; ++i) {
            double x = -half + i * cell, y = -half + j * cell;
            if (i > 0 && i < n && j > 0 && j < n) {
                x += jitter * cell * u(rng);
                y += jitter * cell * u(rng);
            }
            m.vertices.row(j * (n + 1) + i) << x, y, 0.0;
        }
    std::bernoulli_distribution coin(0.5);
    for (int j = 0; j < n; ++j)
        for (int i = 0; i < n; ++i) {
            const std::uint32_t a = std::uint32_t(j * (n + 1) + i), b = a + 1, c = a + std::uint32_t(n + 1) + 1,
                                d = a + std::uint32_t(n + 1);
            const bool flip = random_diagonals ? coin(rng) : ((i + j) % 2 == 1);
            if (flip) {
                m.add_face({a, b, d});
                m.add_face({b, c, d});
            } else {
                m.add_face({a, b, c});
                m.add_face({a, c, d});
            }
        }
    return m;
}

PolygonMesh icosphere(int level, double radius, const Eigen::Vector3d& center) {
    if (level < 0 || level > 9) throw Error("icosphere", "level must be in 0..9");
    const double g = (1 + std::sqrt(5.0)) / 2;
    std::vector<Eigen::Vector3d> v{{-1, g, 0}, {1, g, 0}, {-1, -g, 0}, {1, -g, 0}, {0, -1, g}, {0, 1, g},
                                   {0, -1, -g}, {0, 1, -g}, {g, 0, -1}, {g, 0, 1}, {-g, 0, -1}, {-g, 0, 1}};
    std::vector<std::array<std::uint32_t, 3>> f{{0, 11, 5}, {0, 5, 1},  {0, 1, 7},   {0, 7, 10}, {0, 10, 11},
                                                {1, 5, 9},  {5, 11, 4}, {11, 10, 2}, {10, 7, 6}, {7, 1, 8},
                                                {3, 9, 4},  {3, 4, 2},  {3, 2, 6},   {3, 6, 8},  {3, 8, 9},
                                                {4, 9, 5},  {2, 4, 11}, {6, 2, 10},  {8, 6, 7},  {9, 8, 1}};
    for (auto& x : v) x.normalize();
    for (int l = 0; l < level; ++l) {
        std::map<std::pair<std::uint32_t, std::uint32_t>, std::uint32_t> mid;
        auto midpoint = [&](std::uint32_t a, std::uint32_t b) {
            auto [it, inserted] = mid.try_emplace({std::min(a, b), std::max(a, b)}, std::uint32_t(v.size()));
            if (inserted) v.push_back((v[a] + v[b]).normalized());
            return it->second;
        };
        std::vector<std::array<std::uint32_t, 3>> next;
        next.reserve(4 * f.size());
        for (const auto& t : f) {
            const std::uint32_t ab = midpoint(t[0], t[1]), bc = midpoint(t[1], t[2]), ca = midpoint(t[2], t[0]);
            next.push_back({t[0], ab, ca});
            next.push_back({t[1], bc, ab});
            next.push_back({t[2], ca, bc});
            next.push_back({ab, bc, ca});
        }
        f = std::move(next);
    }
    PolygonMesh m;
    m.vertices.resize(Eigen::Index(v.size()), 3);
    for (std::size_t i = 0; i < v.size(); ++i) m.vertices.row(Eigen::Index(i)) = (center + radius * v[i]).transpose();
    for (const auto& t : f) m.add_face(t.data(), 3);
    return m;
}

PolygonMesh torus_mesh(int n_major, int n_minor, double R, double r) {
    if (n_major < 3 || n_minor < 3 || std::int64_t(n_major) * n_minor > (std::int64_t(1) << 28))
        throw Error("torus_mesh", "needs at least 3 × 3 and at most 2^28 vertices");
    if (!(r > 0 && R > r)) throw Error("torus_mesh", "needs 0 < r < R");
    PolygonMesh m;
    m.vertices.resize(Eigen::Index(n_major) * n_minor, 3);
    auto id = [&](int i, int j) { return std::uint32_t((i % n_major) * n_minor + (j % n_minor)); };
    for (int i = 0; i < n_major; ++i)
        for (int j = 0; j < n_minor; ++j) {
            const double u = 2 * M_PI * i / n_major, v = 2 * M_PI * j / n_minor;
            m.vertices.row(id(i, j)) << (R + r * std::cos(v)) * std::cos(u), (R + r * std::cos(v)) * std::sin(u),
                r * std::sin(v);
        }
    // u around the z axis, v around the tube: (∂u × ∂v) points outward.
    for (int i = 0; i < n_major; ++i)
        for (int j = 0; j < n_minor; ++j) {
            const std::uint32_t a = id(i, j), b = id(i + 1, j), c = id(i + 1, j + 1), d = id(i, j + 1);
            m.add_face({a, b, c});
            m.add_face({a, c, d});
        }
    return m;
}

PolygonMesh double_torus_mesh(int n) {
    if (n < 16 || n > 1024) throw Error("double_torus_mesh", "grid size must be in 16..1024");
    // Two tori (R 0.5, r 0.2) around the z axis, centers 0.85 apart: their tubes merge in the
    // middle into one genus-2 surface, the zero set of the smaller of their distances.
    const Box box{Eigen::Vector3d(-1.3, -1.3, -1.3), Eigen::Vector3d(1.3, 1.3, 1.3)};
    const GridSpec g = GridSpec::cube(n, box);
    const Points nodes = g.nodes();
    std::vector<float> v(g.node_count());
    for (Eigen::Index i = 0; i < nodes.rows(); ++i) {
        const Eigen::Vector3d x = nodes.row(i).transpose();
        double d = INFINITY;
        for (double cx : {-0.425, 0.425}) {
            const double q = std::hypot(x.x() - cx, x.y()) - 0.5;
            d = std::min(d, std::hypot(q, x.z()) - 0.2);
        }
        v[std::size_t(i)] = float(d);
    }
    return contour(g, v, 0.0);
}

}  // namespace gsd::shapes
