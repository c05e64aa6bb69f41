// Making curves: level sets of a per-vertex function as oriented curves on edges ("marching
// triangles"), and damaged copies of curves for tests and demos.
#include <gsd/surface.hpp>

#include "mesh/geometry.hpp"
#include "mesh/topology.hpp"

#include <algorithm>
#include <random>
#include <unordered_map>

namespace gsd {

namespace {

struct Piece {
    std::uint32_t from, to;  // edges crossed (a crossing is identified by its edge: there is one)
    bool used = false;
};

}  // namespace

std::vector<SurfaceCurve> level_set_curves(const SurfaceMesh& mesh, const std::vector<double>& f, double level) {
    const mesh::Topology& t = mesh.topology();
    const mesh::Triangulation& T = t.mesh;
    if (f.size() != T.vertex_count) throw Error("level_set_curves", "expected one value per vertex");
    auto above = [&](std::uint32_t v) { return !(f[v] < level); };
    std::vector<Piece> pieces;
    for (std::size_t fi = 0; fi < T.face_count(); ++fi) {
        if (t.degenerate(fi)) continue;
        const auto& c = T.faces[fi];
        std::array<int, 2> cut{};
        int n = 0;
        for (int k = 0; k < 3 && n < 2; ++k)
            if (above(c[std::size_t(k)]) != above(c[std::size_t((k + 1) % 3)])) cut[std::size_t(n++)] = k;
        if (n != 2) continue;
        // Orient so the corner below the level lies on the left (in the face's own plane).
        const auto p = mesh::layout(mesh::face_lengths(T, fi));
        auto crossing = [&](int k) {
            const double a = f[c[std::size_t(k)]] - level, b = f[c[std::size_t((k + 1) % 3)]] - level;
            const double s = a / (a - b);
            return Eigen::Vector2d((1 - s) * p[std::size_t(k)] + s * p[std::size_t((k + 1) % 3)]);
        };
        const Eigen::Vector2d x0 = crossing(cut[0]), x1 = crossing(cut[1]);
        int below = 0;
        while (above(c[std::size_t(below)])) ++below;
        const Eigen::Vector2d d = x1 - x0, w = p[std::size_t(below)] - x0;
        const bool left = d.x() * w.y() - d.y() * w.x() > 0;
        const std::uint32_t e0 = T.face_edges[fi][std::size_t(cut[0])], e1 = T.face_edges[fi][std::size_t(cut[1])];
        pieces.push_back(left ? Piece{e0, e1} : Piece{e1, e0});
    }
    // Chain pieces: start at crossings nothing leads into (open curves), then close the loops.
    std::unordered_multimap<std::uint32_t, std::size_t> starting;
    std::unordered_map<std::uint32_t, int> incoming;
    for (std::size_t i = 0; i < pieces.size(); ++i) {
        starting.emplace(pieces[i].from, i);
        ++incoming[pieces[i].to];
    }
    auto node = [&](std::uint32_t e) {
        const auto ends = T.edges[e];
        const double a = f[ends[0]] - level, b = f[ends[1]] - level;
        return SurfacePoint::on_edge(e, std::clamp(a / (a - b), 0.0, 1.0));
    };
    std::vector<SurfaceCurve> curves;
    auto follow = [&](std::size_t first) {
        SurfaceCurve c;
        c.nodes.push_back(node(pieces[first].from));
        for (std::size_t i = first;;) {
            pieces[i].used = true;
            c.nodes.push_back(node(pieces[i].to));
            std::size_t next = pieces.size();
            auto [lo, hi] = starting.equal_range(pieces[i].to);
            for (auto it = lo; it != hi; ++it)
                if (!pieces[it->second].used) next = it->second;
            if (next == pieces.size()) break;
            i = next;
        }
        curves.push_back(std::move(c));
    };
    for (std::size_t i = 0; i < pieces.size(); ++i)
        if (!pieces[i].used && incoming[pieces[i].from] == 0) follow(i);
    for (std::size_t i = 0; i < pieces.size(); ++i)
        if (!pieces[i].used) follow(i);
    return curves;
}

SurfaceSources damage(const SurfaceSources& sources, const CurveDamage& d, std::uint64_t seed) {
    if (!(d.cut >= 0 && d.cut < 1)) throw Error("CurveDamage::cut", "must be in [0, 1)");
    if (d.gaps < 1) throw Error("CurveDamage::gaps", "must be at least 1");
    std::mt19937_64 rng(seed);
    SurfaceSources out;
    out.points = sources.points;
    for (const SurfaceCurve& c : sources.curves) {
        if (c.nodes.size() < 2) continue;
        const std::size_t pieces = c.nodes.size() - 1;
        std::vector<std::uint8_t> removed(pieces, 0);
        const auto per_gap = std::size_t(std::lround(d.cut * double(pieces) / d.gaps));
        std::uniform_int_distribution<std::size_t> start(0, pieces - 1);
        for (int g = 0; g < d.gaps && per_gap > 0; ++g) {
            const std::size_t s0 = start(rng);
            for (std::size_t k = 0; k < per_gap; ++k) removed[(s0 + k) % pieces] = 1;
        }
        SurfaceCurve run;
        run.is_signed = c.is_signed;
        for (std::size_t i = 0; i < pieces; ++i) {
            if (!removed[i]) {
                if (run.nodes.empty()) run.nodes.push_back(c.nodes[i]);
                run.nodes.push_back(c.nodes[i + 1]);
            } else if (!run.nodes.empty()) {
                out.curves.push_back(run);
                run.nodes.clear();
            }
        }
        if (!run.nodes.empty()) out.curves.push_back(run);
    }
    // Reverse single pieces: each becomes a curve of its own running the other way.
    for (int r = 0; r < d.reversed; ++r) {
        std::size_t total = 0;
        for (const SurfaceCurve& c : out.curves) total += c.nodes.size() - 1;
        if (total == 0) break;
        std::size_t k = std::uniform_int_distribution<std::size_t>(0, total - 1)(rng), i = 0;
        while (k >= out.curves[i].nodes.size() - 1) k -= out.curves[i++].nodes.size() - 1;
        const SurfaceCurve c = out.curves[i];
        SurfaceCurve before, piece, after;
        before.is_signed = piece.is_signed = after.is_signed = c.is_signed;
        before.nodes.assign(c.nodes.begin(), c.nodes.begin() + std::ptrdiff_t(k + 1));
        piece.nodes = {c.nodes[k + 1], c.nodes[k]};
        after.nodes.assign(c.nodes.begin() + std::ptrdiff_t(k + 1), c.nodes.end());
        out.curves.erase(out.curves.begin() + std::ptrdiff_t(i));
        for (SurfaceCurve* part : {&before, &piece, &after})
            if (part->nodes.size() >= 2) out.curves.push_back(std::move(*part));
    }
    return out;
}

}  // namespace gsd
