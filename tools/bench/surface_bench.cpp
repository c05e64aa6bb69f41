// gsd-surface-bench — accuracy and timing of the Signed Heat Method on surfaces.
//
//   gsd-surface-bench accuracy [--reference PROGRAM] [--work DIR]
//       ε (thesis §4.5) and sign agreement against exact distances on planar and spherical
//       meshes, curves on and off mesh edges, clean and broken. With --reference (a program
//       taking `MESH.obj CURVES.txt -o OUT.npy`, e.g. geometry-central's solver, whose sign is
//       the opposite of gsd's), the same inputs are solved by it too and the ratios printed.
//   gsd-surface-bench timing [--levels 5,6,7,8]
//       setup (factor) and solve times vs mesh size (icospheres), a first solve vs a repeated
//       solve with a new curve, each level-set mode, peak memory.
//   gsd-surface-bench nonbounding
//       curves that bound nothing (thesis §6.4.1): tori with a loop around the tube, L² against
//       L1 integration — the share of the area where |∇φ| is within 10 % of 1, the error of φ
//       against the exact distance along the inner equator, the jumps, the time of step 3 — and
//       curves that do bound a region, where L1 must give the L² result.
//   gsd-surface-bench write LEVEL PREFIX
//       writes PREFIX.obj and PREFIX.txt (an icosphere and a wavy closed curve on it) for
//       side-by-side runs of whole programs.
#include <gsd/io.hpp>
#include <gsd/shapes.hpp>
#include <gsd/surface.hpp>

#include <CLI/CLI.hpp>
#include <Eigen/Geometry>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <functional>
#include <numbers>
#include <optional>
#include <random>
#include <string>
#include <vector>

using namespace gsd;

namespace {

constexpr double kPi = std::numbers::pi;
using Clock = std::chrono::steady_clock;
double since(Clock::time_point t0) { return std::chrono::duration<double>(Clock::now() - t0).count(); }

// ---- exact distances ----------------------------------------------------------------------

double segment_distance(const Eigen::Vector2d& p, const Eigen::Vector2d& a, const Eigen::Vector2d& b) {
    const Eigen::Vector2d d = b - a;
    const double t = std::clamp((p - a).dot(d) / d.squaredNorm(), 0.0, 1.0);
    return (p - a - t * d).norm();
}

/// Signed distance in the plane to closed polylines (negative inside: odd winding).
std::vector<double> planar_truth(const Points& x, const std::vector<std::vector<Eigen::Vector2d>>& loops) {
    std::vector<double> d(std::size_t(x.rows()));
    for (Eigen::Index i = 0; i < x.rows(); ++i) {
        const Eigen::Vector2d p(x(i, 0), x(i, 1));
        double dist = INFINITY, winding = 0;
        for (const auto& L : loops)
            for (std::size_t k = 0; k + 1 < L.size(); ++k) {
                dist = std::min(dist, segment_distance(p, L[k], L[k + 1]));
                const Eigen::Vector2d a = L[k] - p, b = L[k + 1] - p;
                winding += std::atan2(a.x() * b.y() - a.y() * b.x(), a.dot(b));
            }
        d[std::size_t(i)] = std::abs(winding) > kPi ? -dist : dist;
    }
    return d;
}

/// Geodesic distance on the unit sphere from p to the small circle {angle to `axis` = radius},
/// negative inside (toward the axis).
double small_circle_distance(const Eigen::Vector3d& p, const Eigen::Vector3d& axis, double radius) {
    return std::acos(std::clamp(p.normalized().dot(axis), -1.0, 1.0)) - radius;
}

/// Signed geodesic distance on the unit sphere to a closed loop of great-circle arcs through the
/// given unit points; the loop's left (seen from outside) is negative.
double arc_loop_distance(const Eigen::Vector3d& p0, const std::vector<Eigen::Vector3d>& loop) {
    const Eigen::Vector3d p = p0.normalized();
    double best = INFINITY, side = 1;
    for (std::size_t k = 0; k + 1 < loop.size(); ++k) {
        const Eigen::Vector3d a = loop[k], b = loop[k + 1];
        Eigen::Vector3d n = a.cross(b);
        if (n.norm() < 1e-15) continue;
        n.normalize();
        const Eigen::Vector3d q = (p - p.dot(n) * n).normalized();
        const double ab = std::acos(std::clamp(a.dot(b), -1.0, 1.0));
        const double aq = std::acos(std::clamp(a.dot(q), -1.0, 1.0)), qb = std::acos(std::clamp(q.dot(b), -1.0, 1.0));
        double d;
        if (std::abs(aq + qb - ab) < 1e-9) d = std::asin(std::clamp(std::abs(p.dot(n)), 0.0, 1.0));
        else d = std::min(std::acos(std::clamp(p.dot(a), -1.0, 1.0)), std::acos(std::clamp(p.dot(b), -1.0, 1.0)));
        if (d < best) {
            best = d;
            side = p.dot(n) > 0 ? -1.0 : 1.0;
        }
    }
    return side * best;
}

// ---- curves on meshes ------------------------------------------------------------------------

/// The zero set of f as curves with nodes moved to the exact zero of `exact` along each edge
/// (bisection): a curve off the mesh edges that no piecewise-linear function has as zero set.
SurfaceSources exact_crossings(const SurfaceMesh& mesh, const std::function<double(const Eigen::Vector3d&)>& exact) {
    const Points& x = mesh.polygons().vertices;
    std::vector<double> f(mesh.vertex_count());
    for (std::size_t i = 0; i < f.size(); ++i) f[i] = exact(x.row(Eigen::Index(i)).transpose());
    SurfaceSources s;
    s.curves = level_set_curves(mesh, f, 0);
    for (SurfaceCurve& c : s.curves)
        for (SurfacePoint& p : c.nodes) {
            const auto e = mesh.edge(p.index);
            const Eigen::Vector3d a = x.row(e[0]).transpose(), b = x.row(e[1]).transpose();
            const bool a_neg = exact(a) < 0;
            double lo = 0, hi = 1;
            for (int it = 0; it < 60; ++it) {
                const double mid = 0.5 * (lo + hi);
                (exact(a + mid * (b - a)) < 0) == a_neg ? lo = mid : hi = mid;
            }
            p.u = 0.5 * (lo + hi);
        }
    return s;
}

/// A curve along mesh edges near the zero set of f: each crossed edge's endpoint closest to the
/// zero, consecutive repeats dropped (consecutive crossings share a face, so these vertices
/// are joined by edges).
SurfaceSources edge_path(const SurfaceMesh& mesh, const std::vector<double>& f) {
    SurfaceSources s;
    for (const SurfaceCurve& c : level_set_curves(mesh, f, 0)) {
        SurfaceCurve path;
        for (const SurfacePoint& p : c.nodes) {
            const auto e = mesh.edge(p.index);
            const std::uint32_t v = p.u < 0.5 ? e[0] : e[1];
            if (path.nodes.empty() || path.nodes.back().index != v) path.nodes.push_back(SurfacePoint::at_vertex(v));
        }
        if (path.nodes.size() > 2) s.curves.push_back(path);
    }
    return s;
}

std::vector<std::vector<Eigen::Vector2d>> loops_2d(const SurfaceMesh& mesh, const SurfaceSources& s) {
    std::vector<std::vector<Eigen::Vector2d>> loops;
    for (const SurfaceCurve& c : s.curves) {
        std::vector<Eigen::Vector2d> L;
        for (const SurfacePoint& p : c.nodes) L.push_back(position(mesh, p).head<2>());
        loops.push_back(L);
    }
    return loops;
}

// ---- accuracy -----------------------------------------------------------------------------------

struct Case {
    std::string name;
    PolygonMesh mesh;
    SurfaceSources clean;
    std::vector<double> truth;
};

/// Planar meshes of the square [−1,1]²: a wavy closed curve, off the edges and along them.
std::vector<Case> planar_cases() {
    std::vector<Case> out;
    auto wavy = [](const Eigen::Vector3d& x) {
        return std::hypot(1.15 * x.x(), x.y()) - 0.55 - 0.08 * std::sin(3 * std::atan2(x.y(), x.x()) + 0.4);
    };
    struct Kind {
        const char* name;
        int n;
        double jitter;
        bool random;
    };
    for (const Kind k : {Kind{"plane 64² regular", 64, 0.0, false}, Kind{"plane 64² jittered", 64, 0.3, true},
                         Kind{"plane 24² jittered", 24, 0.3, true}}) {
        const PolygonMesh m = shapes::grid_mesh(k.n, k.jitter, k.random, 17);
        const SurfaceMesh mesh(m);
        const SurfaceSources off = exact_crossings(mesh, wavy);
        out.push_back({std::string(k.name) + ", off edges", m, off, planar_truth(m.vertices, loops_2d(mesh, off))});
        std::vector<double> f(mesh.vertex_count());
        for (std::size_t i = 0; i < f.size(); ++i) f[i] = wavy(m.vertices.row(Eigen::Index(i)).transpose());
        const SurfaceSources on = edge_path(mesh, f);
        std::vector<double> on_truth = planar_truth(m.vertices, loops_2d(mesh, on));
        for (const SurfaceCurve& c : on.curves)
            for (const SurfacePoint& p : c.nodes) on_truth[p.index] = 0;  // on the curve
        out.push_back({std::string(k.name) + ", on edges", m, on, on_truth});
    }
    return out;
}

/// Unit spheres: a small circle around a tilted axis through exact edge points (truth: the
/// geodesic distance to the circle) and a path of mesh edges near it (truth: distance to its
/// great-circle arcs).
std::vector<Case> sphere_cases() {
    std::vector<Case> out;
    const Eigen::Vector3d axis = Eigen::Vector3d(0.3, -0.2, 1).normalized();
    const double radius = 1.1;
    auto circle = [&](const Eigen::Vector3d& x) { return small_circle_distance(x, axis, radius); };
    // A UV sphere (poles, slivers near them) and icospheres.
    PolygonMesh uv;
    {
        const int nu = 96, nv = 48;
        uv.vertices.resize(2 + nu * (nv - 1), 3);
        uv.vertices.row(0) << 0, 0, 1;
        uv.vertices.row(1) << 0, 0, -1;
        for (int j = 1; j < nv; ++j)
            for (int i = 0; i < nu; ++i) {
                const double th = kPi * j / nv, ph = 2 * kPi * i / nu;
                uv.vertices.row(2 + (j - 1) * nu + i) << std::sin(th) * std::cos(ph), std::sin(th) * std::sin(ph), std::cos(th);
            }
        auto id = [&](int j, int i) { return std::uint32_t(2 + (j - 1) * nu + (i % nu)); };
        for (int i = 0; i < nu; ++i) {
            uv.add_face({0, id(1, i), id(1, i + 1)});
            uv.add_face({1, id(nv - 1, i + 1), id(nv - 1, i)});
            for (int j = 1; j + 1 < nv; ++j) {
                uv.add_face({id(j, i), id(j + 1, i), id(j + 1, i + 1)});
                uv.add_face({id(j, i), id(j + 1, i + 1), id(j, i + 1)});
            }
        }
    }
    const std::vector<std::pair<std::string, PolygonMesh>> meshes{
        {"icosphere 20k", shapes::icosphere(5)}, {"icosphere 1.3k", shapes::icosphere(3)}, {"UV sphere 9k", uv}};
    for (const auto& [name, m] : meshes) {
        const SurfaceMesh mesh(m);
        std::vector<double> truth(mesh.vertex_count()), f(mesh.vertex_count());
        for (std::size_t i = 0; i < f.size(); ++i) f[i] = truth[i] = circle(m.vertices.row(Eigen::Index(i)).transpose());
        out.push_back({name + ", off edges", m, exact_crossings(mesh, circle), truth});
        const SurfaceSources on = edge_path(mesh, f);
        std::vector<double> on_truth(mesh.vertex_count());
        for (const SurfaceCurve& c : on.curves) {
            std::vector<Eigen::Vector3d> loop;
            for (const SurfacePoint& p : c.nodes) loop.push_back(position(mesh, p).normalized());
            for (std::size_t i = 0; i < on_truth.size(); ++i)
                on_truth[i] = arc_loop_distance(m.vertices.row(Eigen::Index(i)).transpose(), loop);
        }
        for (const SurfaceCurve& c : on.curves)
            for (const SurfacePoint& p : c.nodes) on_truth[p.index] = 0;  // on the curve
        out.push_back({name + ", on edges", m, on, on_truth});
    }
    return out;
}

struct Score {
    double eps = NAN, sign = NAN;
};

Score score(const SurfaceMesh& mesh, const std::vector<double>& phi, const std::vector<double>& truth) {
    for (double x : phi)
        if (!std::isfinite(x)) return {INFINITY, 0};
    return {surface_distance_error(mesh, phi, truth), surface_sign_agreement(mesh, phi, truth)};
}

/// Runs the reference program on files written to `dir`; its φ has the opposite sign.
std::optional<std::vector<double>> run_reference(const std::string& program, const std::string& dir, const Case& c,
                                                 const SurfaceSources& s) {
    const std::string mesh = dir + "/mesh.obj", curves = dir + "/curves.txt", out = dir + "/ref.npy";
    io::write_mesh(mesh, c.mesh);
    write_surface_curves(curves, s);
    std::filesystem::remove(out);
    const std::string cmd = "'" + program + "' '" + mesh + "' '" + curves + "' -o '" + out + "' -q >/dev/null 2>&1";
    if (std::system(cmd.c_str()) != 0 || !std::filesystem::exists(out)) return std::nullopt;
    std::vector<double> phi = io::read_npy(out).data;
    for (double& x : phi) x = -x;
    return phi;
}

int accuracy(const std::string& reference, const std::string& work) {
    std::printf("Accuracy: ε of thesis §4.5 (lower is better) and share of the area with the right sign.\n");
    std::printf("gsd defaults (soft zero set w = 100, t = h², h = half the mean edge)%s\n\n",
                reference.empty() ? "" : "; reference: its defaults (hard zero set), run on the same files");
    std::printf("%-34s %-8s %6s | %10s %8s", "mesh, curve", "input", "pieces", "gsd ε", "sign");
    if (!reference.empty()) std::printf(" | %10s %8s | %9s", "ref ε", "sign", "ε ratio");
    std::printf("\n");
    std::vector<Case> cases = planar_cases();
    for (Case& c : sphere_cases()) cases.push_back(std::move(c));
    std::filesystem::create_directories(work);
    double worst_ratio = 0;
    int sign_losses = 0;
    for (const Case& c : cases) {
        const SurfaceMesh mesh(c.mesh);
        SignedHeatSurface shm(mesh);
        for (const auto& [label, s] : {std::pair<std::string, SurfaceSources>{"clean", c.clean},
                                       std::pair<std::string, SurfaceSources>{"broken", damage(c.clean, {0.4, 3, 1}, 5)}}) {
            std::size_t pieces = 0;
            for (const SurfaceCurve& k : s.curves) pieces += k.nodes.size() - 1;
            const Score ours = score(mesh, shm.solve(s).phi, c.truth);
            std::printf("%-34s %-8s %6zu | %10.3e %8.4f", c.name.c_str(), label.c_str(), pieces, ours.eps, ours.sign);
            if (!reference.empty()) {
                const auto ref = run_reference(reference, work, c, s);
                if (ref) {
                    const Score r = score(mesh, *ref, c.truth);
                    const double ratio = ours.eps / r.eps;
                    worst_ratio = std::max(worst_ratio, ratio);
                    sign_losses += ours.sign < r.sign - 1e-12;
                    std::printf(" | %10.3e %8.4f | %9.3f", r.eps, r.sign, ratio);
                } else {
                    std::printf(" | %10s %8s | %9s", "failed", "", "");
                }
            }
            std::printf("\n");
            std::fflush(stdout);
        }
    }
    if (!reference.empty())
        std::printf("\nworst ε ratio gsd/reference: %.3f; cases where the reference gets the sign right on more area: %d\n",
                    worst_ratio, sign_losses);
    return 0;
}

// ---- timing -------------------------------------------------------------------------------------

/// Resets the process's peak resident memory (Linux), so each size reports its own peak.
void reset_peak_memory() {
    if (std::FILE* f = std::fopen("/proc/self/clear_refs", "w")) {
        std::fputs("5", f);
        std::fclose(f);
    }
}

double peak_memory_mib() {
    std::FILE* f = std::fopen("/proc/self/status", "r");
    if (!f) return NAN;
    char line[256];
    double kib = NAN;
    while (std::fgets(line, sizeof(line), f))
        if (std::strncmp(line, "VmHWM:", 6) == 0) kib = std::atof(line + 6);
    std::fclose(f);
    return kib / 1024;
}

/// A wavy closed curve on the unit sphere through exact edge points.
SurfaceSources wavy_curve(const SurfaceMesh& mesh, double z0, double phase) {
    return exact_crossings(mesh, [&](const Eigen::Vector3d& x) {
        return x.normalized().z() - z0 - 0.2 * std::sin(4 * std::atan2(x.y(), x.x()) + phase) * std::hypot(x.x(), x.y());
    });
}

int timing(const std::vector<int>& levels) {
    std::printf("Timing (seconds, this machine; one process, sizes in increasing order). 'first' is the first\n"
                "solve on a mesh (operators assembled and factored), 'repeat' a later solve with a new curve.\n\n");
    std::printf("%9s %9s %7s | %8s %8s %8s | %8s %8s | %8s %8s %8s | %9s\n", "faces", "vertices", "nodes", "first",
                "(factor)", "repeat", "none 1st", "none rep", "hard rep", "comp rep", "hard it", "peak MiB");
    for (int level : levels) {
        reset_peak_memory();
        const SurfaceMesh mesh(shapes::icosphere(level));
        const SurfaceSources a = wavy_curve(mesh, 0.3, 0.0), b = wavy_curve(mesh, -0.2, 1.0);
        std::size_t nodes = 0;
        for (const SurfaceCurve& c : a.curves) nodes += c.nodes.size();
        auto timed = [](const std::function<SurfaceShmResult()>& f, SurfaceShmResult* out = nullptr) {
            const auto t0 = Clock::now();
            SurfaceShmResult r = f();
            const double s = since(t0);
            if (out) *out = std::move(r);
            return s;
        };
        SignedHeatSurface shm(mesh);
        SurfaceShmResult first_result;
        const double first = timed([&] { return shm.solve(a); }, &first_result);
        const double repeat = timed([&] { return shm.solve(b); });
        SurfaceShmOptions none;
        none.level_set = LevelSetConstraint::None;
        SignedHeatSurface fresh(mesh);
        const double none_first = timed([&] { return fresh.solve(a, none); });
        const double none_repeat = timed([&] { return fresh.solve(b, none); });
        SurfaceShmOptions hard;
        hard.soft_weight = 0;
        timed([&] { return shm.solve(a, hard); });
        SurfaceShmResult hard_result;
        const double hard_repeat = timed([&] { return shm.solve(b, hard); }, &hard_result);
        SurfaceShmOptions comp;
        comp.level_set = LevelSetConstraint::Components;
        const double comp_repeat = timed([&] { return shm.solve(b, comp); });
        std::printf("%9zu %9zu %7zu | %8.3f %8.3f %8.3f | %8.3f %8.3f | %8.3f %8.3f %8zu | %9.0f\n", mesh.triangle_count(),
                    mesh.vertex_count(), nodes, first, first_result.seconds_factor, repeat, none_first, none_repeat,
                    hard_repeat, comp_repeat, hard_result.constraint_iterations, peak_memory_mib());
        std::fflush(stdout);
    }
    return 0;
}

// ---- curves that bound nothing ----------------------------------------------------------------

/// Share of the area where |∇φ| is within 10 % of 1, φ linear on each triangle from its corners.
double unit_slope_share(const SurfaceMesh& mesh, const std::function<double(std::size_t, std::size_t)>& corner) {
    const Points& x = mesh.polygons().vertices;
    double good = 0, total = 0;
    for (std::size_t t = 0; t < mesh.triangle_count(); ++t) {
        const auto c = mesh.triangle(t);
        std::array<Eigen::Vector3d, 3> p;
        for (std::size_t k = 0; k < 3; ++k) p[k] = x.row(c[k]).transpose();
        const Eigen::Vector3d n = (p[1] - p[0]).cross(p[2] - p[0]);
        const double twice_area = n.norm();
        if (!(twice_area > 0)) continue;
        const Eigen::Vector3d u = n / twice_area;
        const Eigen::Vector3d g =
            (corner(t, 0) * u.cross(p[2] - p[1]) + corner(t, 1) * u.cross(p[0] - p[2]) + corner(t, 2) * u.cross(p[1] - p[0])) /
            twice_area;
        total += twice_area;
        if (std::abs(g.norm() - 1) <= 0.1) good += twice_area;
    }
    return good / total;
}

/// Max |(|φ| − d)| / (largest d) along the inner equator of a torus_mesh with a meridian at
/// column 0 (d = (R − r)·min(θ, 2π − θ) exactly there), away from the antipode (|θ − π| > 0.25);
/// infinite if the sign does not flip exactly across the curve and the antipode.
double inner_equator_error(const std::vector<double>& phi, int n_major, int n_minor, double R, double r) {
    double worst = 0;
    int side = 0;
    for (int i = 1; i < n_major; ++i) {
        const double theta = 2 * std::numbers::pi * i / n_major;
        if (std::abs(theta - std::numbers::pi) < 0.25) continue;
        const double d = (R - r) * std::min(theta, 2 * std::numbers::pi - theta);
        const double v = phi[std::size_t(i * n_minor + n_minor / 2)];
        const int s = (v > 0) == (theta < std::numbers::pi) ? 1 : -1;
        if (side == 0) side = s;
        worst = std::max(worst, s == side ? std::abs(std::abs(v) - d) : INFINITY);
    }
    return worst / ((R - r) * std::numbers::pi);
}

int nonbounding() {
    std::printf("tori with one loop around the tube (a meridian along edges), L2 | L1 integration:\n");
    std::printf("%-8s %-10s %8s | %12s %12s | %12s %12s | %5s %9s %9s\n", "R/r", "grid", "faces", "|∇φ|≈1 L2",
                "|∇φ|≈1 L1", "equator L2", "equator L1", "jumps", "step3 L2", "step3 L1");
    for (const auto& [R, r] : {std::pair{0.5, 0.2}, std::pair{0.5, 0.1}, std::pair{0.5, 0.3}})
        for (int n : {16, 24, 32, 48, 64}) {
            const int n_major = 3 * n;
            const SurfaceMesh mesh(shapes::torus_mesh(n_major, n, R, r), "torus");
            SignedHeatSurface shm(mesh);
            SurfaceSources src;
            src.curves.emplace_back();
            for (int j = 0; j <= n; ++j) src.curves.back().nodes.push_back(SurfacePoint::at_vertex(std::uint32_t(j % n)));
            SurfaceShmOptions o;
            o.integration = SurfaceIntegration::L1;
            const SurfaceShmResult l1 = shm.solve(src, o), l2 = shm.solve(src);
            const double s2 = unit_slope_share(mesh, [&](std::size_t t, std::size_t k) { return l2.phi[mesh.triangle(t)[k]]; });
            const double s1 = unit_slope_share(mesh, [&](std::size_t t, std::size_t k) { return l1.corner_phi[t][k]; });
            std::printf("%-8.2g %4dx%-5d %8zu | %12.3f %12.3f | %12.3g %12.3g | %5zu %8.3fs %8.3fs\n", R / r, n_major, n,
                        mesh.triangle_count(), s2, s1, inner_equator_error(l2.phi, n_major, n, R, r),
                        inner_equator_error(l1.phi, n_major, n, R, r), l1.jumps.size(), l2.seconds_integrate,
                        l1.seconds_integrate);
            std::fflush(stdout);
        }
    std::printf("\ncurves that bound a region: L1 against L2 (ε of thesis §4.5 between them), jumps\n");
    auto level_set = [](const PolygonMesh& m, const std::function<double(const Eigen::Vector3d&)>& f) {
        const SurfaceMesh mesh(m);
        std::vector<double> values(mesh.vertex_count());
        for (std::size_t v = 0; v < values.size(); ++v) values[v] = f(m.vertices.row(Eigen::Index(v)).transpose());
        SurfaceSources s;
        s.curves = level_set_curves(mesh, values);
        return s;
    };
    struct Bounding {
        const char* name;
        PolygonMesh mesh;
        std::function<double(const Eigen::Vector3d&)> f;
    };
    const std::vector<Bounding> cases = {
        {"torus 96x32, a small loop", shapes::torus_mesh(96, 32), [](const Eigen::Vector3d& x) { return (x - Eigen::Vector3d(0.7, 0, 0)).norm() - 0.15; }},
        {"torus 96x32, two tube loops", shapes::torus_mesh(96, 32), [](const Eigen::Vector3d& x) { return std::abs(x.y()) - 0.3; }},
        {"sphere 20k, a wavy loop", shapes::icosphere(5), [](const Eigen::Vector3d& x) { return x.z() + 0.2 * x.x() * x.x() - 0.3; }},
        {"double torus, a loop", shapes::double_torus_mesh(64), [](const Eigen::Vector3d& x) { return (x - Eigen::Vector3d(-0.9, 0.3, 0)).norm() - 0.3; }},
    };
    for (const Bounding& c : cases) {
        const SurfaceMesh mesh(c.mesh, c.name);
        SignedHeatSurface shm(mesh);
        const SurfaceSources src = level_set(c.mesh, c.f);
        SurfaceShmOptions o;
        o.integration = SurfaceIntegration::L1;
        const SurfaceShmResult l1 = shm.solve(src, o), l2 = shm.solve(src);
        std::printf("%-30s %8zu faces, %zu curves: ε(L1, L2) %.3g, %zu jumps; step 3 %.3fs (L2 %.3fs)\n", c.name,
                    mesh.triangle_count(), src.curves.size(), surface_distance_error(mesh, l1.phi, l2.phi),
                    l1.jumps.size(), l1.seconds_integrate, l2.seconds_integrate);
        std::fflush(stdout);
    }
    return 0;
}

int write_case(int level, const std::string& prefix) {
    const PolygonMesh m = shapes::icosphere(level);
    const SurfaceMesh mesh(m);
    io::write_mesh(prefix + ".obj", m);
    write_surface_curves(prefix + ".txt", wavy_curve(mesh, 0.3, 0.0));
    std::printf("%s.obj: %zu faces; %s.txt\n", prefix.c_str(), mesh.triangle_count(), prefix.c_str());
    return 0;
}

}  // namespace

int main(int argc, char** argv) {
    CLI::App app{"The Signed Heat Method on surfaces: accuracy against exact distances, and timing (scripts/bench.sh surface)"};
    app.require_subcommand(1);
    std::string reference, work = (std::filesystem::temp_directory_path() / "gsd-surface-bench").string();
    CLI::App* a = app.add_subcommand("accuracy", "ε (thesis §4.5) and sign agreement on planar and spherical meshes");
    a->add_option("--reference", reference, "a program `MESH.obj CURVES.txt -o OUT.npy` solving the same inputs");
    a->add_option("--work", work, "a folder for the reference's files")->capture_default_str();
    std::vector<int> levels{5, 6, 7, 8};
    CLI::App* t = app.add_subcommand("timing", "setup and solve times vs mesh size (icospheres)");
    t->add_option("--levels", levels, "icosphere levels")->delimiter(',')->check(CLI::Range(0, 12))->capture_default_str();
    int level = 0;
    std::string prefix;
    CLI::App* nb = app.add_subcommand("nonbounding", "curves that bound nothing: L2 against L1 integration (thesis §6.4.1)");
    CLI::App* w = app.add_subcommand("write", "an icosphere and a wavy closed curve on it as PREFIX.obj, PREFIX.txt");
    w->add_option("LEVEL", level, "icosphere level")->required()->check(CLI::Range(0, 12));
    w->add_option("PREFIX", prefix, "where to write")->required();
    CLI11_PARSE(app, argc, argv);
    try {
        if (*a) return accuracy(reference, work);
        if (*t) return timing(levels);
        if (*nb) return nonbounding();
        return write_case(level, prefix);
    } catch (const Error& e) {
        std::fprintf(stderr, "gsd-surface-bench: error: %s%s%s\n", e.where().c_str(), e.where().empty() ? "" : ": ", e.what());
        return 1;
    }
}
