// Points in Morton (Z-curve) order: the order in which gsd evaluates query lists, so that
// consecutive queries — a CPU packet, a GPU subgroup — are neighbours, walk the same tree nodes
// and read the same data (3× faster on random queries on the CPU; what keeps a GPU's lanes
// together). Private to the library.
#pragma once

#include <gsd/core.hpp>

#include <cstdint>
#include <vector>

namespace gsd::spatial {

/// The indices of the points in Morton order on a 2^10 grid over their box (stable: equal cells
/// keep their input order). At most 2^32 points.
std::vector<std::uint32_t> morton_order(PointsView q);

/// Whether the GPU paths sort query lists (morton_order) before evaluating them: yes, unless
/// $GSD_QUERY_ORDER=input (measures what the order is worth on a device; results are equal).
bool sort_queries_for_device();

}  // namespace gsd::spatial
