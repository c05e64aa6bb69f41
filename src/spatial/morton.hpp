// Points in Morton (Z-curve) order: the order in which gsd evaluates query lists, so that
// consecutive queries — a CPU packet, a GPU subgroup — are neighbours, walk the same tree nodes
// and read the same data (3× faster on random queries on the CPU; what keeps a GPU's lanes
// together). Private to the library.
#pragma once

#include <gsd/core.hpp>

#include <array>
#include <cstdint>
#include <vector>

namespace gsd::spatial {

/// The indices of the points in Morton order on a 2^10 grid over their box (stable: equal cells
/// keep their input order). At most 2^32 points.
std::vector<std::uint32_t> morton_order(PointsView q);

/// A grid's nodes in bricks of B³ (B = 2 or 4), bricks in C order and nodes in Morton order
/// within a brick: an order a device can take a grid in, so that a subgroup's lanes are a compact
/// block of nodes (a 2×2×2 cube for 8 lanes, 2×2×8 for 32 with B = 2) rather than a run along z,
/// with no order to sort or store. Item i of `items()` is a node, or a copy of one past a side
/// that is not a multiple of B (clamped): such copies are evaluated and dropped
/// (`node(i, ijk, linear)` is false for them). B = 4 pads a side of 5 to 8: the blend takes 2.
class GridBricks {
public:
    /// brick: 2 or 4 (gsd::Error otherwise).
    GridBricks(const GridSpec& grid, int brick);
    std::size_t items() const { return bx_ * by_ * bz_ * per_brick_; }
    /// Item i's node: its indices (clamped into the grid) and, when it is not a copy, its
    /// place in GridSpec storage order; returns false for a copy.
    bool node(std::size_t item, int ijk[3], std::size_t& linear) const;

    /// The items from one on, in turn: node()'s answers with no division per item (node()'s five
    /// were most of the time a 64³ grid's upload took on one core).
    class Cursor {
    public:
        Cursor(const GridBricks& bricks, std::size_t item);
        /// node(item, ijk, linear) for the current item.
        bool node(int ijk[3], std::size_t& linear) const;
        /// On to the next item.
        void next();

    private:
        const GridBricks* b_;
        std::size_t brick_[3];  // the brick's place along x, y, z
        std::size_t m_;         // the item's place in its brick (Morton)
    };

private:
    int nx_, ny_, nz_, bits_;
    std::size_t bx_, by_, bz_, per_brick_;
    std::vector<std::array<std::uint8_t, 3>> offsets_;  // per place in a brick: its offset along x, y, z
};

/// Whether the GPU paths sort query lists (morton_order) before evaluating them: yes, unless
/// $GSD_QUERY_ORDER=input (measures what the order is worth on a device; results are equal).
bool sort_queries_for_device();

}  // namespace gsd::spatial
