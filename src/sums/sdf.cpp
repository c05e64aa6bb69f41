// Signed distance to a mesh as it comes: the sum tree's exact nearest-triangle search for the
// distance, its fast winding numbers for the sign (gsd/sdf.hpp).
#include <gsd/sdf.hpp>
#include <gsd/sums.hpp>

#include "sums/sum_tree.hpp"

#include <algorithm>
#include <cmath>

namespace gsd {

namespace {

void check(const MeshSdfOptions& o, PointsView queries) {
    if (!(o.inside_threshold > 0 && o.inside_threshold < 1))
        throw Error("MeshSdfOptions::inside_threshold", "must be between 0 and 1 (winding numbers are ≈ 1 inside, 0 outside)");
    for (Eigen::Index i = 0; i < queries.rows(); ++i)
        if (!queries.row(i).allFinite()) throw Error("queries", "query " + std::to_string(i) + " is not finite");
}

// Exact distances, each thread over a contiguous run of queries so that each query's search
// starts from its predecessor's nearest triangle (neighbouring queries — a grid's, a sorted
// list's — usually share it, and its distance prunes the search); in blocks, for progress.
std::vector<double> distances(const sums::SumTree& tree, PointsView q, const ProgressFn& progress) {
    const std::size_t n = std::size_t(q.rows());
    std::vector<double> d(n);
    constexpr std::size_t kBlock = std::size_t(1) << 16;
    for (std::size_t first = 0; first < n; first += kBlock) {
        const std::size_t last = std::min(n, first + kBlock);
#pragma omp parallel
        {
            std::uint32_t nearest = std::uint32_t(tree.size());  // none yet
#pragma omp for schedule(static)
            for (std::size_t i = first; i < last; ++i)
                d[i] = tree.nearest_distance(q.row(Eigen::Index(i)).transpose(), INFINITY, &nearest);
        }
        if (progress) progress("distance", double(last) / double(n));
    }
    return d;
}

}  // namespace

MeshSdfResult mesh_sdf(const PolygonMesh& mesh, PointsView queries, const MeshSdfOptions& options,
                       const ProgressFn& progress) {
    validate(mesh, "mesh");
    check(options, queries);
    MeshSdfResult r;
    for_each_triangle(mesh, [&](std::size_t, std::uint32_t, std::uint32_t, std::uint32_t) { ++r.triangles; });
    OrientedElements elements = OrientedElements::from_mesh(mesh);  // drops zero-area triangles
    r.degenerate = r.triangles - elements.size();
    r.triangles = elements.size();
    r.device = "cpu";
    if (queries.rows() == 0) return r;
    const sums::SumTree tree(elements);
    r.phi = distances(tree, queries, progress);
    if (options.sign == SdfSign::winding) {
        WindingOptions w;
        w.device = options.device;
        w.chunk_size = options.chunk_size;
        WindingResult wr = WindingField(std::move(elements), w).winding_numbers(queries, progress);
        for (std::size_t i = 0; i < r.phi.size(); ++i)
            if (wr.w[i] > options.inside_threshold) r.phi[i] = -r.phi[i];
        r.winding = std::move(wr.w);
        r.device = wr.device;
    }
    return r;
}

}  // namespace gsd
