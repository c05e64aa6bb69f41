// The balanced octree and its node graphs (shm/octree.hpp).
#include "shm/octree.hpp"

#include <parallel/algorithm>  // libstdc++'s parallel mode (OpenMP): __gnu_parallel::sort

#include <algorithm>
#include <cmath>
#include <limits>

namespace gsd::shm {

namespace {

std::uint64_t spread(std::uint32_t v) {
    std::uint64_t x = v & 0x1fffffu;
    x = (x | x << 32) & 0x1f00000000ffffULL;
    x = (x | x << 16) & 0x1f0000ff0000ffULL;
    x = (x | x << 8) & 0x100f00f00f00f00fULL;
    x = (x | x << 4) & 0x10c30c30c30c30c3ULL;
    x = (x | x << 2) & 0x1249249249249249ULL;
    return x;
}

std::uint32_t compact(std::uint64_t x) {
    x &= 0x1249249249249249ULL;
    x = (x ^ (x >> 2)) & 0x10c30c30c30c30c3ULL;
    x = (x ^ (x >> 4)) & 0x100f00f00f00f00fULL;
    x = (x ^ (x >> 8)) & 0x1f0000ff0000ffULL;
    x = (x ^ (x >> 16)) & 0x1f00000000ffffULL;
    x = (x ^ (x >> 32)) & 0x1fffffULL;
    return std::uint32_t(x);
}

template <class T>
void sort_unique(std::vector<T>& v) {
    __gnu_parallel::sort(v.begin(), v.end());
    v.erase(std::unique(v.begin(), v.end()), v.end());
}

}  // namespace

std::uint64_t morton3(std::uint32_t x, std::uint32_t y, std::uint32_t z) { return spread(x) | spread(y) << 1 | spread(z) << 2; }

std::array<std::uint32_t, 3> unmorton3(std::uint64_t code) { return {compact(code), compact(code >> 1), compact(code >> 2)}; }

std::uint32_t morton_coordinate(std::uint64_t code, int axis) { return compact(code >> axis); }

namespace {

using Levels = std::vector<std::vector<std::uint64_t>>;

std::ptrdiff_t find_in(const std::vector<std::uint64_t>& v, std::uint64_t code) {
    const auto it = std::lower_bound(v.begin(), v.end(), code);
    return it != v.end() && *it == code ? it - v.begin() : -1;
}

// 2:1 balance across faces, edges and corners: for every cell of level m, the 27 cells of level
// m − 1 around (and including) its parent must exist. A missing one is made by splitting its
// parent (level m − 2), which may require more at m − 2: hence the sweep from the finest level
// up. Then no two touching leaves differ by more than one level, so a leaf's edge holds at
// most one hanging node, at its midpoint.
void balance(Levels& cells, int depth) {
    for (int m = depth; m >= 2; --m) {
        std::vector<std::uint64_t> parents(cells[std::size_t(m)].size());
        std::transform(cells[std::size_t(m)].begin(), cells[std::size_t(m)].end(), parents.begin(),
                       [](std::uint64_t c) { return c >> 3; });
        parents.erase(std::unique(parents.begin(), parents.end()), parents.end());  // sorted already
        const std::int64_t n = std::int64_t(1) << (m - 1);
        const std::vector<std::uint64_t>& above = cells[std::size_t(m) - 1];
        std::vector<std::uint64_t> missing;
#pragma omp parallel
        {
            std::vector<std::uint64_t> mine;
#pragma omp for schedule(static)
            for (std::size_t i = 0; i < parents.size(); ++i) {
                const auto p = unmorton3(parents[i]);
                for (int dx = -1; dx <= 1; ++dx)
                    for (int dy = -1; dy <= 1; ++dy)
                        for (int dz = -1; dz <= 1; ++dz) {
                            const std::int64_t q[3] = {std::int64_t(p[0]) + dx, std::int64_t(p[1]) + dy, std::int64_t(p[2]) + dz};
                            if (q[0] < 0 || q[1] < 0 || q[2] < 0 || q[0] >= n || q[1] >= n || q[2] >= n) continue;
                            const std::uint64_t code = morton3(std::uint32_t(q[0]), std::uint32_t(q[1]), std::uint32_t(q[2]));
                            if (find_in(above, code) < 0) mine.push_back(code >> 3);
                        }
            }
#pragma omp critical
            missing.insert(missing.end(), mine.begin(), mine.end());
        }
        if (missing.empty()) continue;
        sort_unique(missing);
        std::vector<std::uint64_t>& level = cells[std::size_t(m) - 1];
        for (const std::uint64_t q : missing)
            for (std::uint64_t o = 0; o < 8; ++o) level.push_back(q << 3 | o);
        sort_unique(level);
    }
}

}  // namespace

Octree::Octree(const Box& cube, int depth, const SplitRule& rule) : box_(cube), depth_(depth) {
    Levels cells(std::size_t(depth) + 1);
    cells[0] = {0};
    for (int l = 0; l < depth; ++l) {
        const std::vector<std::uint64_t>& parents = cells[std::size_t(l)];
        std::vector<char> split(parents.size(), 0);
        rule(l, parents, split);
        std::vector<std::uint64_t>& children = cells[std::size_t(l) + 1];
        // Children of sorted parents come out sorted: a child's code is its parent's shifted.
        for (std::size_t i = 0; i < parents.size(); ++i)
            if (split[i])
                for (std::uint64_t o = 0; o < 8; ++o) children.push_back(parents[i] << 3 | o);
        if (children.empty()) break;
    }
    balance(cells, depth);
    // Kept: the cells that have children (their eight children are the next level's cells, in
    // order), finest first so that each level's full list is let go as soon as it is read.
    parents_.assign(std::size_t(depth) + 1, {});
    split_.assign(std::size_t(depth) + 1, {});
    for (int l = depth; l >= 0; --l) {
        std::vector<std::uint64_t>& level = cells[std::size_t(l)];
        if (l > 0) {
            std::vector<std::uint64_t>& up = parents_[std::size_t(l) - 1];
            up.resize(level.size() / 8);
            for (std::size_t k = 0; k < up.size(); ++k) up[k] = level[8 * k] >> 3;
        }
        const std::vector<std::uint64_t>& mine = parents_[std::size_t(l)];
        std::vector<std::uint64_t>& bits = split_[std::size_t(l)];
        bits.assign((level.size() + 63) / 64, 0);
        // Both sorted: one merge marks the cells that are parents.
        for (std::size_t i = 0, k = 0; i < level.size() && k < mine.size(); ++i) {
            if (level[i] != mine[k]) continue;
            bits[i >> 6] |= std::uint64_t(1) << (i & 63);
            ++k;
        }
        std::vector<std::uint64_t>().swap(level);
    }
}

std::size_t Octree::cell_count(int level) const {
    return level == 0 ? 1 : 8 * parents_[std::size_t(level) - 1].size();
}

std::uint64_t Octree::cell_code(int level, std::size_t index) const {
    return level == 0 ? 0 : parents_[std::size_t(level) - 1][index >> 3] << 3 | (index & 7);
}

std::ptrdiff_t Octree::find(int level, std::uint64_t code) const {
    if (level == 0) return code == 0 ? 0 : -1;
    const std::ptrdiff_t p = find_in(parents_[std::size_t(level) - 1], code >> 3);
    return p < 0 ? -1 : 8 * p + std::ptrdiff_t(code & 7);
}

std::size_t Octree::cell_count() const {
    std::size_t n = 0;
    for (int l = 0; l <= depth_; ++l) n += cell_count(l);
    return n;
}

std::size_t Octree::leaf_count(int level) const {
    std::size_t n = cell_count(level);
    for (int l = 0; l < level; ++l) n += childless_count(l);
    return n;
}

std::pair<int, std::uint64_t> Octree::leaf_at(int level, const std::array<std::uint32_t, 3>& p) const {
    for (int l = 0;; ++l) {
        const std::uint32_t last = (std::uint32_t(1) << l) - 1;
        const int shift = depth_ - l;
        const std::uint64_t code = morton3(std::min(p[0] >> shift, last), std::min(p[1] >> shift, last), std::min(p[2] >> shift, last));
        if (l == level) return {l, code};
        if (find_in(parents_[std::size_t(l)], code) < 0) return {l, code};  // no children (or no cell)
    }
}

Eigen::Vector3d Octree::to_lattice(const Eigen::Vector3d& x) const {
    const double n = double(std::uint64_t(1) << depth_);
    Eigen::Vector3d u = (x - box_.lo) / lattice_step();
    for (int a = 0; a < 3; ++a) u[a] = std::clamp(u[a], 0.0, n);
    return u;
}

Eigen::Vector3d Octree::to_world(const std::array<std::uint32_t, 3>& p) const {
    return box_.lo + lattice_step() * Eigen::Vector3d(double(p[0]), double(p[1]), double(p[2]));
}

void Octree::for_each_leaf(int level, const std::function<void(int, std::uint64_t)>& f) const {
    for (int l = 0; l <= level && l <= depth_; ++l)
        for (std::size_t i = 0, n = cell_count(l); i < n; ++i)
            if (l == level || !has_children(l, i)) f(l, cell_code(l, i));
}

std::vector<std::pair<int, std::uint64_t>> Octree::leaves(int level) const {
    std::vector<std::pair<int, std::uint64_t>> out;
    out.reserve(leaf_count(level));
    for_each_leaf(level, [&](int l, std::uint64_t c) { out.emplace_back(l, c); });
    return out;
}

namespace {

// A key's LEB128 code: 7 bits a byte, low first, the high bit set on all but the last.
int code_length(std::uint64_t d) {
    int bytes = 1;
    while (d >= 0x80) {
        d >>= 7;
        ++bytes;
    }
    return bytes;
}

}  // namespace

void NodeGraph::pack_keys(std::size_t block) {
    if (keys_packed() || keys.empty()) return;
    if (block == 0) throw Error("NodeGraph::pack_keys: a block needs a key");
    const std::size_t n = keys.size(), blocks = (n + block - 1) / block;
    // Each block's bytes counted, then written in place: nothing in the parallel loops can
    // throw, and `keys` goes only once the packed copy is whole (an allocation that fails
    // leaves the graph as it was).
    const auto delta = [&](std::size_t i) { return i % block == 0 ? keys[i] : keys[i] - keys[i - 1]; };  // ≥ 0: sorted
    std::vector<std::uint64_t> starts(blocks + 1, 0);
#pragma omp parallel for schedule(static)
    for (std::ptrdiff_t b = 0; b < std::ptrdiff_t(blocks); ++b) {
        std::uint64_t bytes = 0;
        for (std::size_t i = std::size_t(b) * block; i < std::min(n, std::size_t(b + 1) * block); ++i) bytes += std::uint64_t(code_length(delta(i)));
        starts[std::size_t(b) + 1] = bytes;
    }
    for (std::size_t b = 0; b < blocks; ++b) starts[b + 1] += starts[b];
    std::vector<std::uint8_t> packed(starts[blocks]);
#pragma omp parallel for schedule(static)
    for (std::ptrdiff_t b = 0; b < std::ptrdiff_t(blocks); ++b) {
        std::uint8_t* out = packed.data() + starts[std::size_t(b)];
        for (std::size_t i = std::size_t(b) * block; i < std::min(n, std::size_t(b + 1) * block); ++i)
            for (std::uint64_t d = delta(i);; d >>= 7) {
                *out++ = std::uint8_t(d & 0x7f) | std::uint8_t(d >= 0x80 ? 0x80 : 0);
                if (d < 0x80) break;
            }
    }
    packed_keys = std::move(packed);
    pack_starts = std::move(starts);
    packed_count = n;
    pack_block = block;
    std::vector<std::uint64_t>().swap(keys);
}

void NodeGraph::unpack_keys() {
    if (!keys_packed()) return;
    const std::size_t n = packed_count, blocks = pack_starts.size() - 1;
    keys.resize(n);
#pragma omp parallel for schedule(dynamic, 1)
    for (std::ptrdiff_t b = 0; b < std::ptrdiff_t(blocks); ++b) {
        const std::uint8_t* at = packed_keys.data() + pack_starts[std::size_t(b)];
        const std::size_t first = std::size_t(b) * pack_block, last = std::min(n, first + pack_block);
        std::uint64_t previous = 0;
        for (std::size_t i = first; i < last; ++i) {
            std::uint64_t d = 0;
            for (int shift = 0;; shift += 7) {
                const std::uint8_t byte = *at++;
                d |= std::uint64_t(byte & 0x7f) << shift;
                if (!(byte & 0x80)) break;
            }
            previous += d;
            keys[i] = previous;
        }
    }
    std::vector<std::uint8_t>().swap(packed_keys);
    std::vector<std::uint64_t>().swap(pack_starts);
    packed_count = pack_block = 0;
}

std::ptrdiff_t NodeGraph::find(std::uint64_t key) const {
    if (keys_packed()) throw Error("NodeGraph::find: the keys are packed (unpack_keys)");
    const auto it = std::lower_bound(keys.begin(), keys.end(), key);
    return it != keys.end() && *it == key ? it - keys.begin() : -1;
}

std::ptrdiff_t NodeGraph::find_near(std::uint64_t key, std::size_t& hint) const {
    if (keys_packed()) throw Error("NodeGraph::find: the keys are packed (unpack_keys)");
    const std::size_t n = keys.size();
    if (n == 0) return -1;
    const std::size_t h = std::min(hint, n - 1);
    // The bracket [lo, hi) that holds the first key ≥ key, by steps doubling away from h.
    std::size_t lo = 0, hi = n;
    if (keys[h] < key) {
        lo = h + 1;
        for (std::size_t step = 1; h + step < n; step *= 2) {
            if (keys[h + step] >= key) {
                hi = h + step + 1;
                break;
            }
            lo = h + step + 1;
        }
    } else {
        hi = h + 1;
        for (std::size_t step = 1; step <= h; step *= 2) {
            if (keys[h - step] < key) {
                lo = h - step + 1;
                break;
            }
            hi = h - step + 1;
        }
    }
    const auto it = std::lower_bound(keys.begin() + std::ptrdiff_t(lo), keys.begin() + std::ptrdiff_t(hi), key);
    hint = std::size_t(it - keys.begin());  // on a miss too: where the key would be
    return it != keys.begin() + std::ptrdiff_t(hi) && *it == key ? std::ptrdiff_t(hint) : -1;
}

namespace {

// The segments' weights from their quarters (V/ℓ² = ℓ·k/4, NodeGraph::weight_code), their
// distinct values (a few dozen) and each one's code. Integers are summed, so the weights do not
// depend on the order the leaves were visited in (float sums of h's multiples would: h need
// not be a power of two).
using Links = std::vector<std::array<std::int32_t, 3>>;

void code_weights(const Links& next, const std::vector<std::array<std::uint8_t, 3>>& quarters, double h, NodeGraph& g) {
    const auto weight = [&](std::size_t i, int a) {
        const std::int32_t j = next[i][std::size_t(a)];
        if (j < 0 || quarters[i][std::size_t(a)] == 0) return 0.0f;
        const double len = double(morton_coordinate(g.keys[std::size_t(j)], a) - morton_coordinate(g.keys[i], a)) * h;
        return float(len * quarters[i][std::size_t(a)] / 4);
    };
    std::vector<float> distinct{0.0f};
#pragma omp parallel
    {
        std::vector<float> mine;
        float last = 0;  // neighbours mostly share their weights: the last one is checked first
#pragma omp for schedule(static) nowait
        for (std::ptrdiff_t i = 0; i < std::ptrdiff_t(g.size()); ++i)
            for (int a = 0; a < 3; ++a)
                if (const float w = weight(std::size_t(i), a); w != last && w != 0) {
                    if (std::find(mine.begin(), mine.end(), w) == mine.end()) mine.push_back(w);
                    last = w;
                }
#pragma omp critical
        distinct.insert(distinct.end(), mine.begin(), mine.end());
    }
    sort_unique(distinct);
    if (distinct.size() > 256) throw Error("the adaptive grid's segments have more than 256 distinct weights (is the octree balanced?)");
    g.weights = std::move(distinct);
    g.weight_code.resize(g.size());
#pragma omp parallel
    {
        float last = 0;
        std::uint8_t last_code = 0;
#pragma omp for schedule(static)
        for (std::ptrdiff_t i = 0; i < std::ptrdiff_t(g.size()); ++i)
            for (int a = 0; a < 3; ++a) {
                const float w = weight(std::size_t(i), a);
                if (w != last) {
                    last = w;
                    last_code = std::uint8_t(std::lower_bound(g.weights.begin(), g.weights.end(), w) - g.weights.begin());
                }
                g.weight_code[std::size_t(i)][std::size_t(a)] = last_code;
            }
    }
}

// The segments as steps (NodeGraph::up, down) from each node's +axis neighbour (-1: none).
void store_steps(const Links& next, std::uint16_t max_step, NodeGraph& g) {
    const std::size_t n = g.size();
    g.up.assign(n, {0, 0, 0});
    g.down.assign(n, {0, 0, 0});
    std::vector<std::pair<std::uint64_t, std::int32_t>> far;
#pragma omp parallel
    {
        std::vector<std::pair<std::uint64_t, std::int32_t>> mine;
        // Each node is the next of at most one node per axis: the writes never collide.
#pragma omp for schedule(static) nowait
        for (std::ptrdiff_t i = 0; i < std::ptrdiff_t(n); ++i)
            for (int a = 0; a < 3; ++a) {
                const std::int32_t j = next[std::size_t(i)][std::size_t(a)];
                if (j < 0) continue;
                const auto step = std::uint64_t(j - i);  // > 0: keys grow along every axis
                const std::uint16_t s = step <= max_step ? std::uint16_t(step) : NodeGraph::kFarStep;
                g.up[std::size_t(i)][std::size_t(a)] = s;
                g.down[std::size_t(j)][std::size_t(a)] = s;
                if (s == NodeGraph::kFarStep) {
                    mine.emplace_back(6 * std::uint64_t(i) + std::uint64_t(a), j);
                    mine.emplace_back(6 * std::uint64_t(j) + 3 + std::uint64_t(a), std::int32_t(i));
                }
            }
#pragma omp critical
        far.insert(far.end(), mine.begin(), mine.end());
    }
    sort_unique(far);
    if (far.size() > std::numeric_limits<std::uint32_t>::max())
        throw Error("the adaptive grid's node graph has more far steps than 32-bit offsets hold (max_step too small?)");
    g.far_slots.resize(far.size());
    g.far_nodes.resize(far.size());
    for (std::size_t k = 0; k < far.size(); ++k) {
        g.far_slots[k] = far[k].first;
        g.far_nodes[k] = far[k].second;
    }
    // Where each block's slots start: a lookup scans its block's few far steps.
    const std::size_t blocks = (n >> NodeGraph::kFarBlockBits) + 1;
    g.far_first.assign(blocks + 1, 0);
    for (std::size_t k = 0; k < far.size(); ++k) ++g.far_first[std::size_t(far[k].first / 6 >> NodeGraph::kFarBlockBits) + 1];
    for (std::size_t b = 0; b < blocks; ++b) g.far_first[b + 1] += g.far_first[b];
}

}  // namespace

std::int32_t NodeGraph::far_node(std::size_t slot) const {
    std::size_t k = far_first[slot / 6 >> kFarBlockBits];
    while (far_slots[k] != slot) ++k;  // a kFarStep has its slot, in its node's block
    return far_nodes[k];
}

NodeGraph build_node_graph(const Octree& tree, int level, std::uint16_t max_step) {
    if (max_step == 0 || max_step >= NodeGraph::kFarStep) throw Error("build_node_graph: max_step must be in [1, 65534]");
    NodeGraph g;
    g.level = level;
    std::vector<std::pair<int, std::uint64_t>> leaves = tree.leaves(level);
    const int D = tree.depth();
    const auto corner = [&](std::size_t leaf, int o) {
        const auto [l, code] = leaves[leaf];
        const std::uint32_t s = std::uint32_t(1) << (D - l);
        const auto c = unmorton3(code);
        return morton3(c[0] * s + std::uint32_t(o & 1) * s, c[1] * s + std::uint32_t(o >> 1 & 1) * s,
                       c[2] * s + std::uint32_t(o >> 2 & 1) * s);
    };
    // The leaves' corners: each run of leaves (neighbours in Morton order within a level) sorts
    // and merges its own first, so the whole list is about a node per leaf instead of eight.
    constexpr std::size_t kRun = 1 << 14;
    const std::size_t runs = (leaves.size() + kRun - 1) / kRun;
    std::vector<std::vector<std::uint64_t>> part(runs);
#pragma omp parallel for schedule(dynamic, 1)
    for (std::ptrdiff_t r = 0; r < std::ptrdiff_t(runs); ++r) {
        std::vector<std::uint64_t>& keys = part[std::size_t(r)];
        const std::size_t first = std::size_t(r) * kRun, last = std::min(leaves.size(), first + kRun);
        keys.reserve(8 * (last - first));
        for (std::size_t i = first; i < last; ++i)
            for (int o = 0; o < 8; ++o) keys.push_back(corner(i, o));
        std::sort(keys.begin(), keys.end());
        keys.erase(std::unique(keys.begin(), keys.end()), keys.end());
        keys.shrink_to_fit();
    }
    std::size_t total = 0;
    for (const auto& k : part) total += k.size();
    g.keys.reserve(total);
    for (auto& k : part) {
        g.keys.insert(g.keys.end(), k.begin(), k.end());
        std::vector<std::uint64_t>().swap(k);
    }
    sort_unique(g.keys);
    g.keys.shrink_to_fit();
    Links next(g.keys.size(), {-1, -1, -1});
    // Each segment's weight counted in quarters of its length first (V/ℓ² = ℓ·k/4: a leaf whose
    // edge the segment is gives 1, a larger leaf whose half-edge it is 4), then coded.
    std::vector<std::array<std::uint8_t, 3>> quarters(g.keys.size(), {0, 0, 0});
    const double h = tree.lattice_step();
    // Each leaf's twelve edges: a quarter of the leaf's volume to each edge of an axis (the four
    // together hold the volume once per axis), split evenly where a hanging node sits at the
    // edge's midpoint (the neighbour across it is finer). The leaf's corners are looked up once,
    // each from where the thread's last leaf found the same corner (leaves in Morton order have
    // their corners near each other's: a few probes instead of a search through every key).
#pragma omp parallel
    {
        std::size_t hint[8 + 12] = {};
#pragma omp for schedule(static)
        for (std::ptrdiff_t i = 0; i < std::ptrdiff_t(leaves.size()); ++i) {
            const auto [l, code] = leaves[std::size_t(i)];
            const std::uint32_t s = std::uint32_t(1) << (D - l);
            const auto c = unmorton3(code);
            std::int32_t at[8];
            for (int o = 0; o < 8; ++o) at[o] = std::int32_t(g.find_near(corner(std::size_t(i), o), hint[o]));
            for (int a = 0; a < 3; ++a) {
                const int b = (a + 1) % 3, d = (a + 2) % 3;
                for (int ob = 0; ob < 2; ++ob)
                    for (int od = 0; od < 2; ++od) {
                        const int o = ob << b | od << d;  // the edge's low corner; its high one adds 1 << a
                        const std::int32_t from = at[o], to = at[o | 1 << a];
                        std::int32_t middle = -1;
                        if (s >= 2) {
                            std::array<std::uint32_t, 3> mid{c[0] * s, c[1] * s, c[2] * s};
                            mid[std::size_t(b)] += std::uint32_t(ob) * s;
                            mid[std::size_t(d)] += std::uint32_t(od) * s;
                            mid[std::size_t(a)] += s / 2;
                            middle = std::int32_t(g.find_near(morton3(mid[0], mid[1], mid[2]), hint[8 + 4 * a + 2 * ob + od]));
                        }
                        // A quarter of the leaf's volume over the segment's length squared is a
                        // quarter of the segment's length, (sh)³/4 / (sh)²; across a hanging node
                        // half that volume over (sh/2)² is the whole half-segment's length.
                        auto add = [&](std::int32_t x, std::int32_t y, std::uint8_t q) {
#pragma omp atomic write
                            next[std::size_t(x)][std::size_t(a)] = y;
#pragma omp atomic
                            quarters[std::size_t(x)][std::size_t(a)] += q;
                        };
                        if (middle >= 0) {
                            add(from, middle, 4);
                            add(middle, to, 4);
                        } else {
                            add(from, to, 1);
                        }
                    }
            }
        }
    }
    std::vector<std::pair<int, std::uint64_t>>().swap(leaves);  // 16 bytes a leaf, not needed below
    code_weights(next, quarters, h, g);
    std::vector<std::array<std::uint8_t, 3>>().swap(quarters);
    store_steps(next, max_step, g);
    return g;
}

int interpolation_weights(const Octree& tree, const NodeGraph& graph, const Eigen::Vector3d& u, std::int32_t (&node)[27],
                          double (&w)[27], double (*dw)[3]) {
    const int D = tree.depth();
    const double top = double(std::uint64_t(1) << D);
    std::array<std::uint32_t, 3> p;
    for (int a = 0; a < 3; ++a) p[std::size_t(a)] = std::uint32_t(std::clamp(std::floor(u[a]), 0.0, top));
    const auto [l, code] = tree.leaf_at(graph.level, p);
    const std::uint32_t s = std::uint32_t(1) << (D - l);
    const auto c = unmorton3(code);
    const std::uint32_t base[3] = {c[0] * s, c[1] * s, c[2] * s};
    // A leaf of the finest level: its corners. A larger one: the octant (half the leaf) that
    // holds the point, whose corners are the leaf's corners, edge midpoints, face centers and
    // center — a node where a finer neighbour put a hanging node there, else the mean of the
    // leaf corners around it. So the field meets the finer side's exactly across every face.
    const std::uint32_t half = s >= 2 ? s / 2 : s;
    std::uint32_t sub[3];
    double t[3];
    for (int a = 0; a < 3; ++a) {
        const double local = (u[a] - double(base[a])) / half;
        sub[a] = s >= 2 && local >= 1 ? 1 : 0;
        t[a] = std::clamp(local - sub[a], 0.0, 1.0);
    }
    int count = 0;
    auto add = [&](std::int32_t n, double weight, const double* grad) {
        for (int k = 0; k < count; ++k)
            if (node[k] == n) {
                w[k] += weight;
                if (dw)
                    for (int a = 0; a < 3; ++a) dw[k][a] += grad[a];
                return;
            }
        node[count] = n;
        w[count] = weight;
        if (dw)
            for (int a = 0; a < 3; ++a) dw[count][a] = grad[a];
        ++count;
    };
    for (int k = 0; k < 8; ++k) {
        const int o[3] = {k & 1, k >> 1 & 1, k >> 2 & 1};
        double f[3], grad[3];
        for (int a = 0; a < 3; ++a) f[a] = o[a] ? t[a] : 1 - t[a];
        const double weight = f[0] * f[1] * f[2];
        for (int a = 0; a < 3; ++a) grad[a] = (o[a] ? 1.0 : -1.0) / half * f[(a + 1) % 3] * f[(a + 2) % 3];
        // The octant corner in halves of the leaf: 0, 1 (a midpoint) or 2 along each axis.
        const std::uint32_t h[3] = {sub[0] + std::uint32_t(o[0]), sub[1] + std::uint32_t(o[1]), sub[2] + std::uint32_t(o[2])};
        const std::uint32_t step = s >= 2 ? half : s;
        const std::ptrdiff_t n = graph.find(morton3(base[0] + h[0] * step, base[1] + h[1] * step, base[2] + h[2] * step));
        if (n >= 0 || s < 2) {
            add(std::int32_t(n), weight, grad);
            continue;
        }
        // Not a node: the mean of the leaf corners it lies between.
        int mids = 0;
        for (int a = 0; a < 3; ++a) mids += h[a] == 1;
        const double share = 1.0 / double(1 << mids);
        double g2[3];
        for (int a = 0; a < 3; ++a) g2[a] = grad[a] * share;
        for (int m = 0; m < (1 << mids); ++m) {
            std::uint32_t q[3];
            int bit = 0;
            for (int a = 0; a < 3; ++a) q[a] = h[a] == 1 ? ((m >> bit++) & 1) * s : (h[a] / 2) * s;
            add(std::int32_t(graph.find(morton3(base[0] + q[0], base[1] + q[1], base[2] + q[2]))), weight * share, g2);
        }
    }
    return count;
}

}  // namespace gsd::shm
