// disjoint_sets.hpp — union–find over the ids 0..n−1 (path halving): the connected components of
// faces, vertices and curve pieces that topology, the surface operators and SWN each need.
#pragma once

#include <cstdint>
#include <numeric>
#include <vector>

namespace gsd::detail {

class DisjointSets {
public:
    explicit DisjointSets(std::size_t n = 0) : parent_(n) { std::iota(parent_.begin(), parent_.end(), 0u); }

    /// A new set holding only the next id; returns that id.
    std::uint32_t add() {
        parent_.push_back(std::uint32_t(parent_.size()));
        return parent_.back();
    }
    std::size_t size() const { return parent_.size(); }

    /// The representative of x's set.
    std::uint32_t find(std::uint32_t x) {
        while (parent_[x] != x) x = parent_[x] = parent_[parent_[x]];
        return x;
    }

    /// Joins the sets of a and b; b's representative stays the representative.
    void join(std::uint32_t a, std::uint32_t b) {
        const std::uint32_t rb = find(b);
        parent_[find(a)] = rb;
    }

private:
    std::vector<std::uint32_t> parent_;
};

}  // namespace gsd::detail
