// delaunay.cpp — see delaunay.hpp.
#include "mesh/delaunay.hpp"

#include <gsd/core.hpp>

#include <algorithm>
#include <cmath>
#include <numeric>

namespace gsd::mesh {

namespace {

constexpr std::uint32_t kNone = UINT32_MAX;

/// Point ids along a Z-order curve: inserted in that order, each point is found by a short
/// walk from the one before (in creation order, crossings would be all over the triangle).
std::vector<std::uint32_t> spatial_order(const std::vector<Vec2>& pos) {
    std::vector<std::uint32_t> order(pos.size());
    std::iota(order.begin(), order.end(), 0u);
    if (pos.size() < 64) return order;
    Vec2 lo = pos[0], hi = pos[0];
    for (const Vec2& x : pos) {
        lo = lo.cwiseMin(x);
        hi = hi.cwiseMax(x);
    }
    const Vec2 scale = (65535.0 / (hi - lo).cwiseMax(1e-300).array()).matrix();
    auto spread = [](std::uint32_t v) {  // the 16 bits of v to the even bits
        v &= 0xffff;
        v = (v | (v << 8)) & 0x00ff00ff;
        v = (v | (v << 4)) & 0x0f0f0f0f;
        v = (v | (v << 2)) & 0x33333333;
        return (v | (v << 1)) & 0x55555555;
    };
    std::vector<std::uint32_t> key(pos.size());
    for (std::size_t i = 0; i < pos.size(); ++i) {
        const Vec2 q = (pos[i] - lo).cwiseProduct(scale);
        key[i] = spread(std::uint32_t(q.x())) | (spread(std::uint32_t(q.y())) << 1);
    }
    std::sort(order.begin(), order.end(), [&](std::uint32_t a, std::uint32_t b) { return key[a] < key[b]; });
    return order;
}

}  // namespace

int ConstrainedDelaunay::back(std::uint32_t t, std::uint32_t from) const {
    const Tri& T = tris_[t];
    return T.n[0] == from ? 0 : T.n[1] == from ? 1 : 2;
}

void ConstrainedDelaunay::link(std::uint32_t t, std::uint32_t from, std::uint32_t to) {
    if (t != kNone) tris_[t].n[std::size_t(back(t, from))] = to;
}

void ConstrainedDelaunay::start(const std::vector<Vec2>& pos) {
    n_ = std::uint32_t(pos.size());
    p_.assign(pos.begin(), pos.end());
    Vec2 lo = pos[0], hi = pos[0];
    for (const Vec2& x : pos) {
        lo = lo.cwiseMin(x);
        hi = hi.cwiseMax(x);
    }
    const Vec2 m = 0.5 * (lo + hi);
    const double s = std::max((hi - lo).maxCoeff(), 1e-300);
    p_.push_back(m + s * Vec2(-30, -10));
    p_.push_back(m + s * Vec2(30, -10));
    p_.push_back(m + s * Vec2(0, 30));
    tris_.assign(1, Tri{{n_, n_ + 1, n_ + 2}, {kNone, kNone, kNone}, {0, 0, 0}});
    vtri_.assign(n_ + 3, 0);
    last_ = 0;
}

ConstrainedDelaunay::Edge ConstrainedDelaunay::locate(const Vec2& x) {
    // Walk towards x, leaving through a random edge that has x beyond it (a walk that cannot
    // cycle with probability 1); a scan of all triangles backs it up.
    std::uint32_t t = last_;
    const std::size_t cap = 4 * tris_.size() + 64;
    for (std::size_t step = 0; step < cap; ++step) {
        const Tri& T = tris_[t];
        int o[3];
        for (int k = 0; k < 3; ++k) o[k] = orient(p_[T.v[std::size_t(k)]], p_[T.v[std::size_t(next(k))]], x);
        random_ = random_ * 6364136223846793005ull + 1442695040888963407ull;
        const int r = int((random_ >> 33) % 3);
        int out = -1;
        for (int i = 0; i < 3 && out < 0; ++i)
            if (o[(r + i) % 3] < 0) out = (r + i) % 3;
        if (out >= 0) {
            t = T.n[std::size_t(out)];
            if (t == kNone) break;
            continue;
        }
        const int zeros = (o[0] == 0) + (o[1] == 0) + (o[2] == 0);
        if (zeros >= 2) throw Error("constrained Delaunay", "internal: two points of a triangle coincide");
        return {t, zeros == 0 ? -1 : (o[0] == 0 ? 0 : o[1] == 0 ? 1 : 2)};
    }
    for (std::uint32_t s = 0; s < tris_.size(); ++s) {
        const Tri& T = tris_[s];
        int o[3];
        for (int k = 0; k < 3; ++k) o[k] = orient(p_[T.v[std::size_t(k)]], p_[T.v[std::size_t(next(k))]], x);
        if (o[0] >= 0 && o[1] >= 0 && o[2] >= 0) return {s, o[0] == 0 ? 0 : o[1] == 0 ? 1 : o[2] == 0 ? 2 : -1};
    }
    throw Error("constrained Delaunay", "internal: a point lies outside its triangle");
}

void ConstrainedDelaunay::insert_point(std::uint32_t p) {
    const Edge at = locate(p_[p]);
    if (at.k < 0) split_triangle(at.tri, p);
    else split_edge(at.tri, at.k, p);
    legalize();
}

void ConstrainedDelaunay::split_triangle(std::uint32_t t, std::uint32_t p) {
    const Tri T = tris_[t];
    const auto [a, b, c] = T.v;
    const std::uint32_t t1 = std::uint32_t(tris_.size()), t2 = t1 + 1;
    tris_[t] = Tri{{a, b, p}, {T.n[0], t1, t2}, {T.fixed[0], 0, 0}};
    tris_.push_back(Tri{{b, c, p}, {T.n[1], t2, t}, {T.fixed[1], 0, 0}});
    tris_.push_back(Tri{{c, a, p}, {T.n[2], t, t1}, {T.fixed[2], 0, 0}});
    link(T.n[1], t, t1);
    link(T.n[2], t, t2);
    vtri_[a] = vtri_[b] = vtri_[p] = t;
    vtri_[c] = t1;
    stack_ = {{t, 0}, {t1, 0}, {t2, 0}};
    last_ = t;
}

void ConstrainedDelaunay::split_edge(std::uint32_t t, int k, std::uint32_t p) {
    // p on edge a→b of t = (a, b, c), shared with u = (b, a, d): four triangles.
    const Tri T = tris_[t];
    const std::uint32_t a = T.v[std::size_t(k)], b = T.v[std::size_t(next(k))], c = T.v[std::size_t(prev(k))];
    const std::uint32_t u = T.n[std::size_t(k)];
    if (u == kNone) throw Error("constrained Delaunay", "internal: a point on the enclosing triangle");
    const Tri U = tris_[u];
    const int j = back(u, t);
    const std::uint32_t d = U.v[std::size_t(prev(j))];
    const std::uint8_t f = T.fixed[std::size_t(k)];
    const std::uint32_t t1 = std::uint32_t(tris_.size()), u1 = t1 + 1;
    tris_[t] = Tri{{a, p, c}, {u1, t1, T.n[std::size_t(prev(k))]}, {f, 0, T.fixed[std::size_t(prev(k))]}};
    tris_.push_back(Tri{{p, b, c}, {u, T.n[std::size_t(next(k))], t}, {f, T.fixed[std::size_t(next(k))], 0}});
    tris_[u] = Tri{{b, p, d}, {t1, u1, U.n[std::size_t(prev(j))]}, {f, 0, U.fixed[std::size_t(prev(j))]}};
    tris_.push_back(Tri{{p, a, d}, {t, U.n[std::size_t(next(j))], u}, {f, U.fixed[std::size_t(next(j))], 0}});
    link(T.n[std::size_t(next(k))], t, t1);
    link(U.n[std::size_t(next(j))], u, u1);
    vtri_[a] = vtri_[c] = vtri_[p] = t;
    vtri_[b] = t1;
    vtri_[d] = u;
    stack_ = {{t, 2}, {t1, 1}, {u, 2}, {u1, 1}};
    last_ = t;
}

bool ConstrainedDelaunay::delaunay_violated(std::uint32_t t, int k) const {
    // The apex across edge k of t = (a, b, c) in the circle of t, tested about a.
    const Tri& T = tris_[t];
    const std::uint32_t u = T.n[std::size_t(k)];
    const std::uint32_t d = tris_[u].v[std::size_t(prev(back(u, t)))];
    return in_circle(p_[T.v[std::size_t(k)]], p_[T.v[std::size_t(next(k))]], p_[T.v[std::size_t(prev(k))]], p_[d]);
}

bool ConstrainedDelaunay::convex(std::uint32_t t, int k) const {
    // The quad of edge k of t = (a, b, c) and its neighbour (b, a, d): flipping to c–d gives
    // (c, a, d) and (d, b, c), both of which must turn counter-clockwise.
    const Tri& T = tris_[t];
    const std::uint32_t u = T.n[std::size_t(k)];
    const std::uint32_t d = tris_[u].v[std::size_t(prev(back(u, t)))];
    const std::uint32_t a = T.v[std::size_t(k)], b = T.v[std::size_t(next(k))], c = T.v[std::size_t(prev(k))];
    return orient(p_[c], p_[a], p_[d]) > 0 && orient(p_[d], p_[b], p_[c]) > 0;
}

void ConstrainedDelaunay::flip(std::uint32_t t, int k) {
    const Tri T = tris_[t];
    const std::uint32_t u = T.n[std::size_t(k)];
    const Tri U = tris_[u];
    const int j = back(u, t);
    const std::uint32_t a = T.v[std::size_t(k)], b = T.v[std::size_t(next(k))], c = T.v[std::size_t(prev(k))];
    const std::uint32_t d = U.v[std::size_t(prev(j))];
    const std::size_t k1 = std::size_t(next(k)), k2 = std::size_t(prev(k));
    const std::size_t j1 = std::size_t(next(j)), j2 = std::size_t(prev(j));
    tris_[t] = Tri{{c, a, d}, {T.n[k2], U.n[j1], u}, {T.fixed[k2], U.fixed[j1], 0}};
    tris_[u] = Tri{{d, b, c}, {U.n[j2], T.n[k1], t}, {U.fixed[j2], T.fixed[k1], 0}};
    link(U.n[j1], u, t);
    link(T.n[k1], t, u);
    vtri_[a] = vtri_[c] = vtri_[d] = t;
    vtri_[b] = u;
}

void ConstrainedDelaunay::legalize() {
    // Edges opposite the new point p (on the stack): flip while p lies in the circle of the
    // triangle across (Lawson).
    while (!stack_.empty()) {
        const auto [t, k] = stack_.back();
        stack_.pop_back();
        const Tri& T = tris_[t];
        const std::uint32_t u = T.n[std::size_t(k)];
        if (u == kNone || T.fixed[std::size_t(k)]) continue;
        if (!delaunay_violated(t, k) || !convex(t, k)) continue;
        flip(t, k);  // t = (p, a, d), u = (d, b, p)
        stack_.push_back({t, 1});
        stack_.push_back({u, 0});
    }
}

ConstrainedDelaunay::Edge ConstrainedDelaunay::find_edge(std::uint32_t a, std::uint32_t b) const {
    // Around a, one way; the fan of a corner of the enclosing triangle is open, so if the walk
    // runs out, the other way too.
    const std::uint32_t first = vtri_[a];
    for (int way = 0; way < 2; ++way) {
        std::uint32_t t = first;
        do {
            const Tri& T = tris_[t];
            const int k = T.v[0] == a ? 0 : T.v[1] == a ? 1 : 2;
            if (T.v[std::size_t(next(k))] == b) return {t, k};
            t = T.n[std::size_t(way == 0 ? prev(k) : k)];
        } while (t != first && t != kNone);
        if (t == first) break;
    }
    return {};
}

void ConstrainedDelaunay::set_fixed(Edge e) {
    Tri& T = tris_[e.tri];
    T.fixed[std::size_t(e.k)] = 1;
    const std::uint32_t u = T.n[std::size_t(e.k)];
    if (u != kNone) tris_[u].fixed[std::size_t(back(u, e.tri))] = 1;
}

std::vector<std::array<std::uint32_t, 2>> ConstrainedDelaunay::crossed_edges(std::uint32_t a, std::uint32_t b) const {
    // The triangle at a whose corner holds the direction to b, then the walk along a → b.
    std::uint32_t t = vtri_[a];
    int k = -1;
    for (std::size_t i = 0; i < tris_.size() && k < 0; ++i) {
        const Tri& T = tris_[t];
        const int ka = T.v[0] == a ? 0 : T.v[1] == a ? 1 : 2;
        const Vec2& x = p_[T.v[std::size_t(next(ka))]];
        const Vec2& y = p_[T.v[std::size_t(prev(ka))]];
        if (orient(p_[a], x, p_[b]) > 0 && orient(p_[a], y, p_[b]) < 0) k = next(ka);
        else t = T.n[std::size_t(prev(ka))];
    }
    if (k < 0) throw Error("constrained Delaunay", "internal: a segment leaves from nowhere");
    std::vector<std::array<std::uint32_t, 2>> crossed;
    for (;;) {
        const Tri& T = tris_[t];
        if (T.fixed[std::size_t(k)]) throw Error("constrained Delaunay", "internal: two segments cross");
        const std::uint32_t x = T.v[std::size_t(k)], y = T.v[std::size_t(next(k))];
        crossed.push_back({x, y});
        const std::uint32_t u = T.n[std::size_t(k)];
        const int j = back(u, t);
        const std::uint32_t w = tris_[u].v[std::size_t(prev(j))];
        if (w == b) return crossed;
        // u = (y, x, w): leave through the side of w that is still crossed.
        const int s = orient(p_[a], p_[b], p_[w]);
        if (s == 0) throw Error("constrained Delaunay", "internal: a point lies on a segment");
        const bool x_right = orient(p_[a], p_[b], p_[x]) < 0;
        // Edge j+1 of u is x → w, edge j+2 is w → y.
        k = (s > 0) == x_right ? next(j) : prev(j);
        t = u;
    }
}

void ConstrainedDelaunay::insert_segment(std::uint32_t a, std::uint32_t b) {
    if (a == b) return;
    if (const Edge e = find_edge(a, b); e.tri != kNone) return set_fixed(e);
    // Sloan's method: flip crossed edges whose quad is convex until none crosses a → b.
    std::vector<std::array<std::uint32_t, 2>> queue = crossed_edges(a, b);
    const std::size_t cap = 1000 + 64 * queue.size() * queue.size();
    for (std::size_t head = 0; head < queue.size(); ++head) {
        if (head > cap) throw Error("constrained Delaunay", "internal: a segment could not be inserted");
        const auto [x, y] = queue[head];
        const Edge e = find_edge(x, y);
        if (e.tri == kNone) throw Error("constrained Delaunay", "internal: a crossed edge vanished");
        if (!convex(e.tri, e.k)) {
            queue.push_back({x, y});
            continue;
        }
        flip(e.tri, e.k);  // the new edge is c–d: corners 0 and 2 of e.tri
        const std::uint32_t c = tris_[e.tri].v[0], d = tris_[e.tri].v[2];
        if (c != a && c != b && d != a && d != b && properly_cross(p_[a], p_[b], p_[c], p_[d])) queue.push_back({c, d});
    }
    const Edge e = find_edge(a, b);
    if (e.tri == kNone) throw Error("constrained Delaunay", "internal: a segment is missing after insertion");
    set_fixed(e);
}

void ConstrainedDelaunay::drop_outside() {
    // Everything reachable from the enclosing triangle's corners without crossing a segment.
    outside_.assign(tris_.size(), 0);
    std::vector<std::uint32_t> pending;
    for (std::uint32_t t = 0; t < tris_.size(); ++t)
        for (std::uint32_t v : tris_[t].v)
            if (v >= n_ && !outside_[t]) {
                outside_[t] = 1;
                pending.push_back(t);
            }
    while (!pending.empty()) {
        const std::uint32_t t = pending.back();
        pending.pop_back();
        for (int k = 0; k < 3; ++k) {
            const std::uint32_t u = tris_[t].n[std::size_t(k)];
            if (u != kNone && !tris_[t].fixed[std::size_t(k)] && !outside_[u]) {
                outside_[u] = 1;
                pending.push_back(u);
            }
        }
    }
}

void ConstrainedDelaunay::make_delaunay() {
    // Lawson flips over the inside, segments kept; capped (an unfinished pass is still valid).
    stack_.clear();
    for (std::uint32_t t = 0; t < tris_.size(); ++t)
        if (!outside_[t])
            for (int k = 0; k < 3; ++k) stack_.push_back({t, k});
    std::size_t budget = 64 * tris_.size() + 1000;
    while (!stack_.empty() && budget > 0) {
        const auto [t, k] = stack_.back();
        stack_.pop_back();
        const Tri& T = tris_[t];
        const std::uint32_t u = T.n[std::size_t(k)];
        if (u == kNone || outside_[u] || T.fixed[std::size_t(k)]) continue;
        if (!delaunay_violated(t, k) || !convex(t, k)) continue;
        flip(t, k);
        --budget;
        stack_.insert(stack_.end(), {{t, 0}, {t, 1}, {u, 0}, {u, 1}});
    }
}

void ConstrainedDelaunay::drop_flat_triangles(double min_height) {
    // A triangle flatter than min_height keeps its orientation in the plane (the tests are
    // exact) but not in 3D, where positions are rounded: three points of one side (collinear,
    // but rounding can bulge one out by 1e-17), or three points along a piece with the chord
    // between the outer two (such a triangle can be Delaunay: its circle is huge). Its long
    // edge is flipped towards a point off that line instead. Where several lie side by side,
    // only the outermost can flip at first: passes until none is left.
    for (int pass = 0; pass < 64; ++pass) {
        bool flipped = false;
        for (std::uint32_t t = 0; t < tris_.size(); ++t) {
            if (outside_[t]) continue;
            const Tri& T = tris_[t];
            int k = 0;  // the longest edge
            for (int i = 1; i < 3; ++i)
                if ((p_[T.v[std::size_t(next(i))]] - p_[T.v[std::size_t(i)]]).squaredNorm() >
                    (p_[T.v[std::size_t(next(k))]] - p_[T.v[std::size_t(k)]]).squaredNorm())
                    k = i;
            const Vec2 &a = p_[T.v[std::size_t(k)]], &b = p_[T.v[std::size_t(next(k))]], &c = p_[T.v[std::size_t(prev(k))]];
            if (std::abs(cross(b - a, c - a)) >= min_height * (b - a).norm()) continue;
            const std::uint32_t u = T.n[std::size_t(k)];
            if (u == kNone || outside_[u] || T.fixed[std::size_t(k)] || !convex(t, k)) continue;
            flip(t, k);
            flipped = true;
        }
        if (!flipped) return;
    }
}

void ConstrainedDelaunay::run(const std::vector<Vec2>& pos, double min_height, const std::vector<std::uint32_t>& boundary,
              const std::vector<std::array<std::uint32_t, 2>>& segments, std::vector<std::array<std::uint32_t, 3>>& out) {
    start(pos);
    for (std::uint32_t i : spatial_order(pos)) insert_point(i);
    for (std::size_t i = 0; i < boundary.size(); ++i) insert_segment(boundary[i], boundary[(i + 1) % boundary.size()]);
    for (const auto& s : segments) insert_segment(s[0], s[1]);
    drop_outside();
    make_delaunay();
    drop_flat_triangles(min_height);
    out.clear();
    for (std::uint32_t t = 0; t < tris_.size(); ++t)
        if (!outside_[t]) out.push_back(tris_[t].v);
}

}  // namespace gsd::mesh
