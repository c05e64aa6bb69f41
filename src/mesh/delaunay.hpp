// delaunay.hpp — a constrained Delaunay triangulation of a polygon with points and segments
// inside it, in the plane, built with exact orientation tests (predicates.hpp). Private to
// src/mesh (cutting a mesh along curves, split.cpp, triangulates each cut triangle with it).
#pragma once

#include "mesh/predicates.hpp"

#include <array>
#include <cstdint>
#include <vector>

namespace gsd::mesh {

/// A constrained Delaunay triangulation of a polygon with points and segments inside it:
/// points go into a big enclosing triangle one by one (Lawson flips), segments are forced in by
/// flipping the edges they cross (Sloan), the outside of the polygon is dropped, the rest is
/// flipped to Delaunay and triangles too flat for 3D are flipped away. Requires that no segment
/// crosses another or passes through a point (the arrangement guarantees it); then every step
/// is a valid triangulation, whatever the rounding: every flip is checked with exact tests.
class ConstrainedDelaunay {
public:
    /// Triangles (counter-clockwise, ids into `pos`) covering the polygon `boundary`
    /// (counter-clockwise) with all of `pos` as vertices and every segment as an edge.
    /// Triangles flatter than `min_height` are flipped away where they can be.
    void run(const std::vector<Vec2>& pos, double min_height, const std::vector<std::uint32_t>& boundary,
             const std::vector<std::array<std::uint32_t, 2>>& segments, std::vector<std::array<std::uint32_t, 3>>& out);

private:
    struct Tri {
        std::array<std::uint32_t, 3> v;      // corners, counter-clockwise
        std::array<std::uint32_t, 3> n;      // n[k]: the triangle across edge v[k] → v[k+1]
        std::array<std::uint8_t, 3> fixed;   // edge k is a segment
    };
    struct Edge {
        std::uint32_t tri = UINT32_MAX;
        int k = 0;
    };

    static int next(int k) { return k == 2 ? 0 : k + 1; }
    static int prev(int k) { return k == 0 ? 2 : k - 1; }
    int back(std::uint32_t t, std::uint32_t from) const;
    void link(std::uint32_t t, std::uint32_t from, std::uint32_t to);
    void start(const std::vector<Vec2>& pos);
    Edge locate(const Vec2& x);
    void insert_point(std::uint32_t p);
    void split_triangle(std::uint32_t t, std::uint32_t p);
    void split_edge(std::uint32_t t, int k, std::uint32_t p);
    bool delaunay_violated(std::uint32_t t, int k) const;
    bool convex(std::uint32_t t, int k) const;
    void flip(std::uint32_t t, int k);
    void legalize();
    Edge find_edge(std::uint32_t a, std::uint32_t b) const;
    void set_fixed(Edge e);
    void insert_segment(std::uint32_t a, std::uint32_t b);
    std::vector<std::array<std::uint32_t, 2>> crossed_edges(std::uint32_t a, std::uint32_t b) const;
    void drop_outside();
    void make_delaunay();
    void drop_flat_triangles(double min_height);

    std::vector<Vec2> p_;
    std::vector<Tri> tris_;
    std::vector<std::uint32_t> vtri_;  // a triangle at each vertex
    std::vector<std::uint8_t> outside_;
    std::vector<Edge> stack_;
    std::uint32_t n_ = 0;              // real points; the enclosing triangle's corners follow
    std::uint32_t last_ = 0;           // where point location starts
    std::uint64_t random_ = 0x9e3779b97f4a7c15ull;
};

}  // namespace gsd::mesh
