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

/// A grid's nodes in bricks of B³ (B = 2 or 4), bricks in C order and nodes in Morton order
/// within a brick: the order a device takes a grid in, so that a subgroup's lanes are a compact
/// block of nodes (a 2×2×2 cube for 8 lanes) rather than a run along z, with no order to sort
/// or store. Item i of `items()` is a node, or a copy of one past an odd edge (clamped): such
/// copies are evaluated and dropped (`node(i, linear)` is false for them).
class GridBricks {
public:
    GridBricks(const GridSpec& grid, int brick);
    std::size_t items() const { return bx_ * by_ * bz_ * per_brick_; }
    /// Item i's node: its indices (clamped into the grid) and, when it is not a copy, its
    /// place in GridSpec storage order; returns false for a copy.
    bool node(std::size_t item, int ijk[3], std::size_t& linear) const;

private:
    int nx_, ny_, nz_, bits_;
    std::size_t bx_, by_, bz_, per_brick_;
};

/// Whether the GPU paths sort query lists (morton_order) before evaluating them: yes, unless
/// $GSD_QUERY_ORDER=input (measures what the order is worth on a device; results are equal).
bool sort_queries_for_device();

}  // namespace gsd::spatial
