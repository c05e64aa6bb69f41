// Face areas and the mesh's typical edge length, with the degeneracy rules every surface method
// shares (src/mesh/topology.hpp's thresholds).
#include "mesh/geometry.hpp"

#include "mesh/topology.hpp"

#include <gsd/core.hpp>

#include <algorithm>
#include <cmath>
#include <cstdint>

namespace gsd::mesh {

std::vector<double> face_areas(const Triangulation& T) {
    // Degenerate: flat to rounding relative to its own sides, or so small against the mesh
    // (sides ~1e-6 of the mean edge, e.g. vertices that coincide up to rounding) that its
    // stiffness would meet a mass of 1e-12 of its neighbours' and make the operators singular.
    // The mesh's scale is a robust mean (gsd::robust_mean): with a plain one, a single vertex
    // moved 10⁷ edges away made every ordinary face "degenerate".
    std::vector<double> lengths;
    lengths.reserve(T.edge_lengths.size());
    for (double l : T.edge_lengths)
        if (l > 0 && std::isfinite(l)) lengths.push_back(l);
    const double mean = robust_mean(std::move(lengths));
    const double tiny = kDegenerateAbsoluteArea * mean * mean;
    std::vector<double> a(T.face_count());
    for (std::size_t f = 0; f < T.face_count(); ++f) {
        const auto l = face_lengths(T, f);
        const double longest = std::max({l[0], l[1], l[2]});
        const double area = triangle_area(l[0], l[1], l[2]);
        a[f] = area > kDegenerateRelativeArea * longest * longest && area > tiny && longest <= kDegenerateSpan * mean ? area : 0.0;
    }
    return a;
}

double mean_edge_length(const Triangulation& T, const std::vector<double>& areas) {
    std::vector<std::uint8_t> counted(T.edge_count(), 0);
    std::vector<double> lengths;
    for (std::size_t f = 0; f < T.face_count(); ++f) {
        if (areas[f] <= 0) continue;
        for (std::uint32_t e : T.face_edges[f])
            if (!counted[e]) {
                counted[e] = 1;
                lengths.push_back(T.edge_lengths[e]);
            }
    }
    return robust_mean(std::move(lengths));  // one stray vertex must not set the diffusion time
}

}  // namespace gsd::mesh
