// The adaptive grid of the adaptive SHM: a 2:1-balanced octree over a cube, and the node graph
// of the octree cut off at any level (its multigrid levels).
//
// Cells are addressed per level by the Morton code of their integer coordinates (i, j, k) ∈
// [0, 2^l)³; each level keeps the sorted codes of its cells that have children (parents sorted
// ⇒ children sorted: a level's cells are its parents' children in order), so the tree costs
// about a byte a cell and a lookup is a binary search. Nodes (cell
// corners) live on the finest lattice, coordinates in [0, 2^D]³, also keyed by Morton code.
#pragma once

#include <gsd/core.hpp>

#include <array>
#include <cstdint>
#include <functional>
#include <span>
#include <vector>

namespace gsd::shm {

/// Morton code of three coordinates of up to 21 bits each (x in the lowest bit).
std::uint64_t morton3(std::uint32_t x, std::uint32_t y, std::uint32_t z);
/// Its inverse.
std::array<std::uint32_t, 3> unmorton3(std::uint64_t code);
/// One coordinate of it (axis 0, 1 or 2).
std::uint32_t morton_coordinate(std::uint64_t code, int axis);

class Octree {
public:
    /// Deepest level: node coordinates 2^D must fit 21 bits.
    static constexpr int kMaxDepth = 20;

    /// Which cells of a level to split: `split[i]` for cell `codes[i]` of `level`. Called once a
    /// level, top down; the callee may run in parallel.
    using SplitRule = std::function<void(int level, std::span<const std::uint64_t> codes, std::vector<char>& split)>;

    /// Refines the cube `cube` (equal extents) by `rule` down to `depth`, then balances it 2:1
    /// across faces, edges and corners (cells are added, never removed).
    Octree(const Box& cube, int depth, const SplitRule& rule);

    int depth() const { return depth_; }
    const Box& box() const { return box_; }
    /// World size of a cell of `level`; of the finest lattice's step at depth().
    double cell_size(int level) const { return box_.extent().x() / double(std::uint64_t(1) << level); }
    double lattice_step() const { return cell_size(depth_); }
    /// Cells of `level` in Morton order: how many, the code of the index-th, whether it has
    /// children. The tree keeps only the cells that have children (a split makes all eight, so
    /// they are the next level's cells): about a byte a cell instead of a code's eight.
    std::size_t cell_count(int level) const;
    std::uint64_t cell_code(int level, std::size_t index) const;
    bool has_children(int level, std::size_t index) const { return split_[std::size_t(level)][index >> 6] >> (index & 63) & 1; }
    /// Index of a cell in its level, or -1.
    std::ptrdiff_t find(int level, std::uint64_t code) const;
    std::size_t cell_count() const;
    /// Leaves of the tree cut at `level` (cells of `level` count as leaves).
    std::size_t leaf_count(int level) const;
    /// Cells of `level` that have no children (the whole tree's leaves there).
    std::size_t childless_count(int level) const { return cell_count(level) - parents_[std::size_t(level)].size(); }

    /// The leaf of the tree cut at `level` that holds lattice point p (coordinates in
    /// [0, 2^D]; points on a face go to the cell above them, the box's far faces to the last
    /// cell): its level and code.
    std::pair<int, std::uint64_t> leaf_at(int level, const std::array<std::uint32_t, 3>& p) const;
    /// Lattice coordinates (continuous) of a world point, clamped to the box.
    Eigen::Vector3d to_lattice(const Eigen::Vector3d& x) const;
    Eigen::Vector3d to_world(const std::array<std::uint32_t, 3>& p) const;

    /// Visits every leaf of the tree cut at `level`: f(leaf level, code). Serial.
    void for_each_leaf(int level, const std::function<void(int, std::uint64_t)>& f) const;
    /// Every leaf of the tree cut at `level` as (level, code) pairs.
    std::vector<std::pair<int, std::uint64_t>> leaves(int level) const;

private:
    Box box_;
    int depth_ = 0;
    std::vector<std::vector<std::uint64_t>> parents_;  ///< per level: the sorted codes of its cells that have children
    std::vector<std::vector<std::uint64_t>> split_;    ///< per level: a bit a cell, set where it has children
};

/// The nodes of the octree cut at a level, and the least-squares gradient graph on them: each
/// axis-parallel segment between adjacent nodes along a leaf's edge, with the volume V it stands
/// for (a quarter of each leaf it borders per edge, halved where a hanging node splits the
/// edge). Σ_segments V (Δφ/ℓ − Ȳ·e)² is then a quadrature of ∫|∇φ − Y|² over the box. Kept
/// per node: 8 + 6 + 6 + 3 bytes.
struct NodeGraph {
    /// Marks a step kept aside, in far_slots and far_nodes (NodeGraph::up, down).
    static constexpr std::uint16_t kFarStep = 0xffff;

    int level = 0;
    std::vector<std::uint64_t> keys;  ///< sorted Morton codes of lattice points
    /// The segments as steps through the keys: the node along +axis a from node i (the segment's
    /// other end) is i + up[i][a], the one along −axis a is i − down[i][a]; 0: no segment. A
    /// Morton code grows with each coordinate, so a +axis neighbour always comes later. Steps
    /// are short but where the order carries into high bits (about 1.5 % at 16 bits): those are
    /// kFarStep, their node kept in `far_nodes` under the slot 6i + a (up) or 6i + 3 + a (down)
    /// in the sorted `far_slots`, whose first slot of each block of 2^kFarBlockBits nodes is
    /// at far_first[block]. 12 bytes a node instead of two int32 indices' 24.
    std::vector<std::array<std::uint16_t, 3>> up, down;
    std::vector<std::uint64_t> far_slots;
    std::vector<std::int32_t> far_nodes;
    std::vector<std::uint32_t> far_first;
    static constexpr int kFarBlockBits = 5;
    /// The weights V/ℓ² of the segments, as codes into `weights`. A weight is ℓ·k/4, ℓ a power
    /// of two times h and k ≤ 13 an integer: each of the segment's up to four leaves gives ℓ/4,
    /// or ℓ where the segment is half a larger leaf's edge (at most three can be). So a level has
    /// at most 7·(D + 6) distinct weights and a byte names each. k is counted as an integer
    /// while the graph is built, so a weight, float(ℓ·k/4), does not depend on the order the
    /// leaves were visited in.
    std::vector<std::array<std::uint8_t, 3>> weight_code;
    std::vector<float> weights;  ///< the distinct weights; weights[0] = 0 (no segment)

    /// The node along +axis a from node i, or -1 (no segment).
    std::int32_t next(std::size_t i, int a) const {
        const std::uint16_t s = up[i][std::size_t(a)];
        if (s == 0) return -1;
        return s != kFarStep ? std::int32_t(i + s) : far_node(6 * i + std::size_t(a));
    }
    /// The node along −axis a from node i (whose next it is), or -1.
    std::int32_t prev(std::size_t i, int a) const {
        const std::uint16_t s = down[i][std::size_t(a)];
        if (s == 0) return -1;
        return s != kFarStep ? std::int32_t(i - s) : far_node(6 * i + 3 + std::size_t(a));
    }
    /// The keys delta-coded while nothing reads them (the solve walks the steps alone): about a
    /// byte a key instead of 8. pack_keys() moves them into `packed_keys` and frees `keys`;
    /// unpack_keys() restores them, the same. Neither does anything twice. `block`: keys a block
    /// (blocks are coded and decoded in parallel).
    void pack_keys(std::size_t block = std::size_t(1) << 16);
    void unpack_keys();
    bool keys_packed() const { return !packed_keys.empty(); }
    std::vector<std::uint8_t> packed_keys;   ///< blocks of pack_block keys, LEB128 deltas from the block's first
    std::vector<std::uint64_t> pack_starts;  ///< each block's offset in packed_keys; one more at the end
    std::size_t packed_count = 0, pack_block = 0;

    /// V/ℓ² of the segment (i, next(i, a)) (world units), 0 where there is none.
    float weight(std::size_t i, int a) const { return weights[weight_code[i][std::size_t(a)]]; }
    std::size_t size() const { return keys_packed() ? packed_count : keys.size(); }
    /// Index of a node, or -1.
    std::ptrdiff_t find(std::uint64_t key) const;
    /// The same, searched outward from `hint` (any index; a nearby key's makes it a few probes),
    /// which is set to where the key is, or would be.
    std::ptrdiff_t find_near(std::uint64_t key, std::size_t& hint) const;
    std::ptrdiff_t find(const std::array<std::uint32_t, 3>& p) const { return find(morton3(p[0], p[1], p[2])); }

private:
    std::int32_t far_node(std::size_t slot) const;
};

/// The node graph of the tree cut at `level`. `max_step`: the longest step kept in up/down
/// (longer ones go to `far`; below the default only to test that path).
NodeGraph build_node_graph(const Octree& tree, int level, std::uint16_t max_step = NodeGraph::kFarStep - 1);

/// Interpolation weights of a point (continuous lattice coordinates, inside the box) in the
/// leaf of the tree cut at `graph.level` that holds it: trilinear from the leaf's corners in a
/// leaf of the finest level; in a larger one, trilinear in the octant that holds the point,
/// whose corners are nodes where finer neighbours made hanging nodes and otherwise means of the
/// leaf's corners — so the field is continuous across changes of level. Up to 27 (node,
/// weight) pairs, and with `dw` the weights' derivatives along the lattice axes. Returns the count.
int interpolation_weights(const Octree& tree, const NodeGraph& graph, const Eigen::Vector3d& lattice, std::int32_t (&node)[27],
                          double (&w)[27], double (*dw)[3] = nullptr);

}  // namespace gsd::shm
