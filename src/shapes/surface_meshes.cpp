// Meshes for the surface methods' tests, benchmarks and demos: a flat square and an icosphere,
// whose exact geodesic distances are known.
#include <gsd/shapes.hpp>

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

}  // namespace gsd::shapes
