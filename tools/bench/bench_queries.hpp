// Query sets shared by the benchmarks (gsd-bench, gsd-gpu-bench).
#pragma once

#include <gsd/shapes.hpp>

#include <random>

namespace gsd::bench {

/// Half the queries near the surface (within noise 0.02: the expensive case for the accelerated
/// sums), half uniform in [−1, 1]³.
inline Points queries_near(const shapes::Shape& shape, std::size_t m, std::uint64_t seed) {
    const PointCloud near = shape.sample(m / 2, seed);
    std::mt19937_64 rng(seed + 1);
    std::normal_distribution<double> noise(0, 0.02);
    std::uniform_real_distribution<double> u(-1, 1);
    Points q(Eigen::Index(m), 3);
    for (Eigen::Index i = 0; i < q.rows(); ++i)
        for (int a = 0; a < 3; ++a) q(i, a) = i < near.size() ? near.points(i, a) + noise(rng) : u(rng);
    return q;
}

}  // namespace gsd::bench
