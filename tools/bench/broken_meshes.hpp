// broken_meshes.hpp — the damage the broken-mesh benches apply (gsd-broken-bench, gsd-sdf-bench),
// besides shapes::corrupt's holes, flips and noise.
#pragma once

#include <gsd/core.hpp>

#include <algorithm>
#include <random>
#include <vector>

namespace gsd::bench {

/// The mesh scaled and centered into [−0.9, 0.9]³ (its longest side 1.8).
inline PolygonMesh normalized(PolygonMesh m) {
    const Box b = bounding_box(m.vertices);
    const Eigen::RowVector3d center = 0.5 * (b.lo + b.hi).transpose();
    const double scale = 1.8 / b.extent().maxCoeff();
    for (Eigen::Index i = 0; i < m.vertices.rows(); ++i) m.vertices.row(i) = (m.vertices.row(i) - center) * scale;
    return m;
}

/// One face in `every` again (random faces, seeded), every other copy reversed.
inline PolygonMesh with_duplicates(PolygonMesh m, std::size_t every, std::uint64_t seed) {
    std::mt19937_64 rng(seed);
    const std::size_t n = m.face_count();
    for (std::size_t k = 0; k < n / every; ++k) {
        const std::size_t f = rng() % n;
        std::vector<std::uint32_t> face(m.indices.begin() + m.offsets[f], m.indices.begin() + m.offsets[f + 1]);
        if (k % 2) std::reverse(face.begin(), face.end());
        m.add_face(face.data(), face.size());
    }
    return m;
}

}  // namespace gsd::bench
