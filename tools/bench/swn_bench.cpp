// gsd-swn-bench — Surface Winding Numbers: accuracy on a synthetic benchmark and timing.
//
//   gsd-swn-bench accuracy [--cases N] [--only MESH] [--torus N] [--double-torus N] [--curve-weight W]
//                          [--reference PROGRAM] [--work DIR] [--quiet]
//       A benchmark in the style of thesis §6.3: on a sphere, a torus and a double torus, the
//       regions below a level of a random low-frequency function are the ground truth; their
//       boundaries (on mesh edges, or across faces), clean or with 30 % / 50 % cut away, plus
//       broken loops around handles that bound nothing, are the input. Prints the mislabeled
//       area (up to a global integer shift: the meshes are closed) of SWN with the full and the
//       reduced program, naive rounding of u, and the sign of the surface Signed Heat Method.
//       With --reference (a program `REF MESH.obj CURVES.txt -o PREFIX` writing
//       PREFIX.labels.npy, e.g. the SWN reference code), cases on mesh edges are solved by it too.
//       --only MESH keeps the cases on one mesh (sphere, torus, double-torus); --torus N and
//       --double-torus N change their resolutions (72 and 36: torus_mesh(N, N/3), double_torus_mesh(N)),
//       to check that a change holds on meshes it was not measured on.
//   gsd-swn-bench timing [--sizes 32,48,64,96,128] [--clp-max 48]
//       Time per step and full vs reduced program vs mesh size: double tori with broken loops;
//       the network solver vs CLP on the same program for sizes up to --clp-max.
//   gsd-swn-bench broken-loops [--seeds N] [--cut C] [--reference PROGRAM] [--work DIR]
//       Tori (resolution 48 + 12·seed) carrying one small bounding loop (the boundary of a random
//       disk) and one loop around the tube, both on mesh edges and broken: C (0.3) cut away in 3
//       gaps and one piece reversed; --around hole: the outer equator instead of the loop around the tube.
//       (write broken-loops/SEED[/CUT] writes one, cut 0.3 by default.) The mislabeled area of SWN
//       (reduced, full, reduced without close_gaps) and the reference, case by case, and their means.
//   gsd-swn-bench section71 [--meshes N] [--reference PROGRAM] [--work DIR] [--quiet]
//       Thesis §7.1's comparison: closed meshes of about 5k vertices (genus 0 and 1 in turn, bent
//       at random), five cases each: the region below a random level of one of the five lowest
//       nonconstant Laplacian eigenfunctions is the truth; its boundary along edges plus the
//       boundary of the region one ring larger or smaller (a parallel copy) is the curve, half of
//       it deleted at random intervals. Inside/outside mislabeled by SWN (its labels contoured as
//       the thesis does: from the level most often seen across the curves), the best threshold of
//       its labels, SHM's sign, SHM's sign on SWN's bounding part, and the reference.
//       (write section71/MESH/EIGENFUNCTION writes one.)
//   gsd-swn-bench write CASE PREFIX [--torus N] [--double-torus N]
//       Writes one accuracy case (by name, at the sizes given to accuracy) as PREFIX.obj,
//       PREFIX.txt and PREFIX.truth.npy for side-by-side runs.
#include <gsd/io.hpp>
#include <gsd/shapes.hpp>
#include <gsd/surface.hpp>
#include <gsd/swn.hpp>

#include "core/disjoint_sets.hpp"
#include "laplace_eigen.hpp"

#include <CLI/CLI.hpp>
#include <Eigen/Geometry>

#include <algorithm>
#include <chrono>
#include <climits>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <functional>
#include <optional>
#include <map>
#include <numbers>
#include <numeric>
#include <random>
#include <set>
#include <string>
#include <vector>

using namespace gsd;

namespace {

using Clock = std::chrono::steady_clock;
double since(Clock::time_point t0) { return std::chrono::duration<double>(Clock::now() - t0).count(); }
constexpr double kPi = std::numbers::pi;

// ---- cases ---------------------------------------------------------------------------------

struct Case {
    std::string name;
    PolygonMesh mesh;
    SurfaceSources curves;
    std::vector<int> truth;  // per face
    bool on_edges = false;
};

Eigen::Vector3d vertex(const PolygonMesh& m, std::uint32_t v) { return m.vertices.row(v).transpose(); }
const std::uint32_t* face(const PolygonMesh& m, std::size_t f) { return m.indices.data() + m.offsets[f]; }

/// A random low-frequency function: three plane waves of wavelength about the shape's size.
struct Waves {
    std::array<Eigen::Vector3d, 3> k;
    std::array<double, 3> phase{}, amplitude{};
    double level = 0;
    double operator()(const Eigen::Vector3d& x) const {
        double s = 0;
        for (std::size_t i = 0; i < 3; ++i) s += amplitude[i] * std::cos(k[i].dot(x) + phase[i]);
        return s - level;
    }
};

Waves random_waves(std::mt19937_64& rng, const PolygonMesh& m) {
    std::normal_distribution<double> n(0, 1);
    std::uniform_real_distribution<double> u(0, 1);
    Waves w;
    for (std::size_t i = 0; i < 3; ++i) {
        const double dz = n(rng), dy = n(rng), dx = n(rng);  // a fixed order (GCC's), any compiler
        const Eigen::Vector3d d(dx, dy, dz);
        w.k[i] = d.normalized() * (2.0 + 2.0 * u(rng));
        w.phase[i] = 2 * kPi * u(rng);
        w.amplitude[i] = 0.5 + u(rng);
    }
    // The level puts 20–45 % of the vertices below it.
    std::vector<double> values;
    for (Eigen::Index v = 0; v < m.vertices.rows(); ++v) values.push_back(w(m.vertices.row(v).transpose()));
    std::sort(values.begin(), values.end());
    w.level = values[std::size_t((0.2 + 0.25 * u(rng)) * double(values.size() - 1))];
    return w;
}

/// Per face: 1 where most of it lies below zero (f linear over the face, sampled).
std::vector<int> truth_below(const PolygonMesh& m, const std::vector<double>& f) {
    std::vector<int> t(m.face_count());
    for (std::size_t i = 0; i < t.size(); ++i) {
        const std::uint32_t* v = face(m, i);
        int below = 0, total = 0;
        for (int a = 0; a <= 6; ++a)
            for (int b = 0; a + b <= 6; ++b) {
                const double x = (a * f[v[0]] + b * f[v[1]] + (6 - a - b) * f[v[2]]) / 6.0;
                below += x < 0;
                ++total;
            }
        t[i] = 2 * below > total;
    }
    return t;
}

/// The boundary of a face region as curves along mesh edges, the region on their left, keeping
/// the edges `keep` accepts (by midpoint). Pieces chained where one ends where the next starts.
std::vector<SurfaceCurve> region_boundary(const PolygonMesh& m, const std::vector<int>& inside,
                                          const std::function<bool(const Eigen::Vector3d&)>& keep) {
    std::map<std::pair<std::uint32_t, std::uint32_t>, int> side;  // directed halfedge → face label
    for (std::size_t f = 0; f < m.face_count(); ++f) {
        const std::uint32_t* v = face(m, f);
        for (int k = 0; k < 3; ++k) side[{v[k], v[(k + 1) % 3]}] = inside[f];
    }
    std::multimap<std::uint32_t, std::uint32_t> next;
    for (const auto& [h, label] : side) {
        if (!label) continue;
        auto twin = side.find({h.second, h.first});
        if (twin == side.end() || twin->second) continue;
        if (keep(0.5 * (vertex(m, h.first) + vertex(m, h.second)))) next.insert({h.first, h.second});
    }
    std::vector<SurfaceCurve> out;
    while (!next.empty()) {
        SurfaceCurve c;
        auto it = next.begin();
        std::uint32_t a = it->first;
        c.nodes.push_back(SurfacePoint::at_vertex(a));
        while ((it = next.find(a)) != next.end()) {
            a = it->second;
            next.erase(it);
            c.nodes.push_back(SurfacePoint::at_vertex(a));
        }
        out.push_back(std::move(c));
    }
    return out;
}

/// Whether every component of the faces with label `label` (joined through edges) is a disk
/// (Euler characteristic 1): then every loop bounding them bounds on its own.
bool all_disks(const PolygonMesh& m, const std::vector<int>& labels, int label) {
    std::map<std::pair<std::uint32_t, std::uint32_t>, std::vector<std::uint32_t>> edge_faces;
    for (std::size_t f = 0; f < m.face_count(); ++f)
        if (labels[f] == label)
            for (int k = 0; k < 3; ++k) {
                const std::uint32_t a = face(m, f)[k], b = face(m, f)[(k + 1) % 3];
                edge_faces[{std::min(a, b), std::max(a, b)}].push_back(std::uint32_t(f));
            }
    detail::DisjointSets components(m.face_count());
    for (const auto& [e, fs] : edge_faces)
        for (std::size_t i = 1; i < fs.size(); ++i) components.join(fs[i], fs[0]);
    std::map<std::uint32_t, long> chi;
    std::map<std::uint32_t, std::map<std::uint32_t, int>> vertices;
    for (const auto& [e, fs] : edge_faces) {
        const std::uint32_t r = components.find(fs[0]);
        chi[r] -= 1;
        vertices[r][e.first] = vertices[r][e.second] = 1;
    }
    for (std::size_t f = 0; f < m.face_count(); ++f)
        if (labels[f] == label) chi[components.find(std::uint32_t(f))] += 1;
    for (auto& [r, c] : chi)
        if (c + long(vertices[r].size()) != 1) return false;
    return true;
}

/// A loop around a handle (it bounds nothing): where the half-plane through `axis_point`
/// containing the z direction and direction (cos θ, sin θ, 0) meets the surface — one loop
/// around the tube. On mesh edges: the part of the boundary of {n·(x − c) < 0} on that side.
std::vector<SurfaceCurve> handle_loop(const SurfaceMesh& mesh, const PolygonMesh& m, const Eigen::Vector3d& c,
                                      double theta, bool on_edges, bool reverse) {
    const Eigen::Vector3d d(std::cos(theta), std::sin(theta), 0), n(-std::sin(theta), std::cos(theta), 0);
    std::vector<SurfaceCurve> loops;
    if (on_edges) {
        std::vector<int> below(m.face_count());
        for (std::size_t f = 0; f < m.face_count(); ++f) {
            const std::uint32_t* v = face(m, f);
            below[f] = n.dot((vertex(m, v[0]) + vertex(m, v[1]) + vertex(m, v[2])) / 3 - c) < 0;
        }
        loops = region_boundary(m, below, [&](const Eigen::Vector3d& x) {
            return (x - c).dot(d) > 0 && (x - c).dot(d) < 0.75;
        });
    } else {
        std::vector<double> g(mesh.vertex_count());
        for (std::size_t v = 0; v < g.size(); ++v) g[v] = n.dot(vertex(m, std::uint32_t(v)) - c);
        for (SurfaceCurve& k : level_set_curves(mesh, g, 0)) {
            Eigen::Vector3d mean = Eigen::Vector3d::Zero();
            for (const SurfacePoint& p : k.nodes) mean += position(mesh, p);
            mean /= double(k.nodes.size());
            if ((mean - c).dot(d) > 0 && (mean - c).dot(d) < 0.75) loops.push_back(std::move(k));
        }
    }
    if (reverse)
        for (SurfaceCurve& k : loops) std::reverse(k.nodes.begin(), k.nodes.end());
    return loops;
}

/// Resolutions of the benchmark's tori: torus_mesh(torus, torus / 3), double_torus_mesh(double_torus).
struct MeshSizes {
    int torus = 72, double_torus = 36;
};

/// The benchmark: every mesh × curves on/off edges × clean / 30 % / 50 % cut, `per` random
/// functions each (nonbounding handle loops on the torus and double torus).
std::vector<Case> make_cases(int per, const MeshSizes& sizes = {}) {
    struct MeshKind {
        std::string name;
        PolygonMesh mesh;
        std::vector<Eigen::Vector3d> holes;  // points on the axes of the handles
    };
    std::vector<MeshKind> meshes;
    meshes.push_back({"sphere", shapes::icosphere(4), {}});
    meshes.push_back({"torus", shapes::torus_mesh(sizes.torus, sizes.torus / 3), {Eigen::Vector3d::Zero()}});
    meshes.push_back({"double-torus", shapes::double_torus_mesh(sizes.double_torus), {{-0.425, 0, 0}, {0.425, 0, 0}}});
    std::vector<Case> cases;
    for (std::size_t mi = 0; mi < meshes.size(); ++mi) {
        const MeshKind& k = meshes[mi];
        const SurfaceMesh mesh(k.mesh, k.name);
        for (int i = 0; i < per; ++i) {
            std::mt19937_64 rng(std::uint64_t(1000 * mi + 17 * i + 1));
            std::uniform_real_distribution<double> u(0, 1);
            // Region boundaries that bound nothing on their own (a band around a handle) would
            // make the extra handle loops ambiguous (which loop of a homologous set is the extra
            // one is a tie SWN cannot break): draw functions until the regions, or what lies
            // outside them, are all disks.
            Waves w;
            for (int attempt = 0; attempt < 100; ++attempt) {
                w = random_waves(rng, k.mesh);
                std::vector<int> inside(k.mesh.face_count());
                for (std::size_t t = 0; t < inside.size(); ++t) {
                    const std::uint32_t* v = face(k.mesh, t);
                    inside[t] = w((vertex(k.mesh, v[0]) + vertex(k.mesh, v[1]) + vertex(k.mesh, v[2])) / 3) < 0;
                }
                if (all_disks(k.mesh, inside, 1) || all_disks(k.mesh, inside, 0)) break;
            }
            std::vector<double> f(mesh.vertex_count());
            for (std::size_t v = 0; v < f.size(); ++v) f[v] = w(vertex(k.mesh, std::uint32_t(v)));
            for (bool on_edges : {true, false}) {
                Case base;
                base.mesh = k.mesh;
                base.on_edges = on_edges;
                SurfaceSources src;
                if (on_edges) {
                    base.truth.resize(k.mesh.face_count());
                    for (std::size_t t = 0; t < base.truth.size(); ++t) {
                        const std::uint32_t* v = face(k.mesh, t);
                        base.truth[t] = w((vertex(k.mesh, v[0]) + vertex(k.mesh, v[1]) + vertex(k.mesh, v[2])) / 3) < 0;
                    }
                    src.curves = region_boundary(k.mesh, base.truth, [](const Eigen::Vector3d&) { return true; });
                } else {
                    base.truth = truth_below(k.mesh, f);
                    src.curves = level_set_curves(mesh, f, 0);
                }
                // Handle loops (bound nothing): one per handle, random side and orientation. On
                // mesh edges, one sharing an edge with a region's boundary would merge with it
                // (the chain is their sum): such angles are skipped.
                std::set<std::pair<std::uint32_t, std::uint32_t>> used;
                if (on_edges)
                    for (const SurfaceCurve& c : src.curves)
                        for (std::size_t n = 0; n + 1 < c.nodes.size(); ++n)
                            used.insert(std::minmax(c.nodes[n].index, c.nodes[n + 1].index));
                for (const Eigen::Vector3d& hole : k.holes) {
                    const bool reverse = u(rng) < 0.5;
                    for (int attempt = 0; attempt < 50; ++attempt) {
                        double theta = 2 * kPi * u(rng);
                        if (k.holes.size() > 1 && std::cos(theta) * hole.x() < 0) theta = kPi - theta;  // outer side
                        std::vector<SurfaceCurve> loops = handle_loop(mesh, k.mesh, hole, theta, on_edges, reverse);
                        bool shares = false;
                        for (const SurfaceCurve& c : loops)
                            for (std::size_t n = 0; n + 1 < c.nodes.size(); ++n)
                                shares = shares || used.count(std::minmax(c.nodes[n].index, c.nodes[n + 1].index));
                        if (shares && attempt + 1 < 50) continue;
                        for (SurfaceCurve& c : loops) src.curves.push_back(std::move(c));
                        break;
                    }
                }
                for (double cut : {0.0, 0.3, 0.5}) {
                    Case c = base;
                    char name[96];
                    std::snprintf(name, sizeof(name), "%s/%d/%s/cut%.0f%%", k.name.c_str(), i,
                                  on_edges ? "edges" : "faces", 100 * cut);
                    c.name = name;
                    c.curves = cut > 0 ? damage(src, {cut, 3, 0}, std::uint64_t(1000 * mi + 31 * i + (on_edges ? 7 : 9))) : src;
                    cases.push_back(std::move(c));
                }
            }
        }
    }
    return cases;
}

// ---- the reference program ------------------------------------------------------------------

/// Labels per input face from a run of the reference, or nothing if it failed or refused.
std::optional<std::vector<int>> run_reference(const std::string& program, const Case& c, const std::string& dir,
                                              double& seconds) {
    const std::string prefix = dir + "/ref";
    io::write_mesh(prefix + "_in.obj", c.mesh);
    write_surface_curves(prefix + "_in.txt", c.curves);
    std::filesystem::remove(prefix + ".labels.npy");
    std::filesystem::remove(prefix + ".mesh.obj");
    const std::string cmd = "'" + program + "' '" + prefix + "_in.obj' '" + prefix + "_in.txt' -o '" + prefix +
                            "' >'" + prefix + ".log' 2>&1";
    const auto t0 = Clock::now();
    const int rc = std::system(cmd.c_str());
    seconds = since(t0);
    if (rc != 0 || !std::filesystem::exists(prefix + ".labels.npy")) return std::nullopt;
    const io::NpyArray a = io::read_npy(prefix + ".labels.npy");
    std::vector<int> ref;
    for (double x : a.data) ref.push_back(std::isfinite(x) ? int(std::lround(x)) : 0);
    if (ref.size() == c.mesh.face_count()) return ref;
    // The reference split edges: map its faces back to input faces (centroid inside), by area.
    if (!std::filesystem::exists(prefix + ".mesh.obj")) return std::nullopt;
    const PolygonMesh rm = io::read_mesh(prefix + ".mesh.obj");
    if (rm.face_count() != ref.size()) return std::nullopt;
    std::vector<std::vector<std::uint32_t>> incident(std::size_t(c.mesh.vertices.rows()));
    for (std::size_t f = 0; f < c.mesh.face_count(); ++f)
        for (int k = 0; k < 3; ++k) incident[face(c.mesh, f)[k]].push_back(std::uint32_t(f));
    std::vector<std::map<int, double>> votes(c.mesh.face_count());
    for (std::size_t g = 0; g < rm.face_count(); ++g) {
        const std::uint32_t* v = face(rm, g);
        const Eigen::Vector3d p = (vertex(rm, v[0]) + vertex(rm, v[1]) + vertex(rm, v[2])) / 3;
        const double area = 0.5 * (vertex(rm, v[1]) - vertex(rm, v[0])).cross(vertex(rm, v[2]) - vertex(rm, v[0])).norm();
        std::size_t best = SIZE_MAX;
        double best_score = -INFINITY;
        for (int k = 0; k < 3; ++k) {
            if (v[k] >= incident.size()) continue;
            for (std::uint32_t f : incident[v[k]]) {
                const std::uint32_t* w = face(c.mesh, f);
                const Eigen::Vector3d a = vertex(c.mesh, w[0]), b = vertex(c.mesh, w[1]), d = vertex(c.mesh, w[2]);
                const Eigen::Vector3d n = (b - a).cross(d - a);
                const double score = std::min({(b - a).cross(p - a).dot(n), (d - b).cross(p - b).dot(n), (a - d).cross(p - d).dot(n)});
                if (score > best_score) {
                    best_score = score;
                    best = f;
                }
            }
        }
        if (best != SIZE_MAX) votes[best][ref[g]] += area;
    }
    std::vector<int> out(c.mesh.face_count(), 0);
    for (std::size_t f = 0; f < out.size(); ++f)
        if (!votes[f].empty())
            out[f] = std::max_element(votes[f].begin(), votes[f].end(), [](auto& a, auto& b) { return a.second < b.second; })->first;
    return out;
}

// ---- inside/outside from labels ---------------------------------------------------------------

/// Inside (1) or outside (0) from integer winding numbers, as the thesis' §7.1 contours them:
/// along the input curves (on mesh edges), the label on the higher side of each edge where the
/// two sides differ, weighted by length; the most frequent one m is where inside begins
/// (label ≥ m). Ties: the smaller. With no such edge, everything is outside.
std::vector<int> inside_by_curve_levels(const PolygonMesh& m, const std::vector<int>& labels, const SurfaceSources& curves) {
    std::map<std::pair<std::uint32_t, std::uint32_t>, std::size_t> left;  // directed edge → its face
    for (std::size_t f = 0; f < m.face_count(); ++f)
        for (int k = 0; k < 3; ++k) left[{face(m, f)[k], face(m, f)[(k + 1) % 3]}] = f;
    std::map<int, double> votes;
    for (const SurfaceCurve& c : curves.curves)
        for (std::size_t i = 0; i + 1 < c.nodes.size(); ++i) {
            const std::uint32_t a = c.nodes[i].index, b = c.nodes[i + 1].index;
            const auto l = left.find({a, b}), r = left.find({b, a});
            if (l == left.end() || r == left.end() || labels[l->second] == labels[r->second]) continue;
            votes[std::max(labels[l->second], labels[r->second])] += (vertex(m, a) - vertex(m, b)).norm();
        }
    const int start = votes.empty() ? INT_MAX
                                    : std::max_element(votes.begin(), votes.end(), [](auto& x, auto& y) {
                                          return x.second < y.second;
                                      })->first;
    std::vector<int> inside(labels.size());
    for (std::size_t f = 0; f < labels.size(); ++f) inside[f] = labels[f] >= start;
    return inside;
}

/// The smallest mislabeled area over every threshold "label ≥ m" (what the best possible
/// contouring of these winding numbers would give): separates SWN's completion from its contouring.
double best_threshold_error(const SurfaceMesh& mesh, const std::vector<int>& labels, const std::vector<int>& truth) {
    std::set<int> values(labels.begin(), labels.end());
    values.insert(*values.rbegin() + 1);
    double best = 1;
    for (int m : values) {
        std::vector<int> inside(labels.size());
        for (std::size_t f = 0; f < labels.size(); ++f) inside[f] = labels[f] >= m;
        best = std::min(best, mislabeled_area(mesh, inside, truth, false));
    }
    return best;
}

// ---- accuracy ------------------------------------------------------------------------------

struct Stats {
    std::vector<double> v;
    void add(double x) { v.push_back(x); }
    double mean() const {
        double s = 0;
        for (double x : v) s += x;
        return v.empty() ? NAN : s / double(v.size());
    }
    double median() const {
        if (v.empty()) return NAN;
        std::vector<double> s = v;
        std::sort(s.begin(), s.end());
        return s[s.size() / 2];
    }
    double max() const { return v.empty() ? NAN : *std::max_element(v.begin(), v.end()); }
};

struct AccuracyArgs {
    int per = 3;
    std::string reference, work, only;
    MeshSizes sizes;
    bool quiet = false;
    SwnOptions defaults;
};

int accuracy(AccuracyArgs args) {
    const int per = args.per;
    const std::string &reference = args.reference, &only = args.only;
    std::string& work = args.work;
    const MeshSizes sizes = args.sizes;
    const bool quiet = args.quiet;
    const SwnOptions& defaults = args.defaults;
    if (work.empty()) work = std::filesystem::temp_directory_path().string() + "/gsd-swn-bench";
    std::filesystem::create_directories(work);
    std::vector<Case> cases = make_cases(per, sizes);
    if (!only.empty()) {
        std::erase_if(cases, [&](const Case& c) { return c.name.substr(0, c.name.find('/')) != only; });
        if (cases.empty()) {
            std::fprintf(stderr, "no cases on a mesh named %s (sphere, torus, double-torus)\n", only.c_str());
            return 2;
        }
    }
    const std::vector<std::string> methods = {"swn-full", "swn-reduced", "naive-u", "shm-sign", "reference"};
    std::map<std::string, std::map<std::string, Stats>> by_group;  // group → method → mislabeled %
    Stats full_vs_reduced, objective_gap, t_full, t_reduced, t_ref;
    std::size_t equal_optimum = 0, programs = 0;
    if (!quiet)
        std::printf("%-34s %7s %9s %9s %9s %9s %9s   %7s %7s %7s\n", "case", "faces", "full %", "reduced %", "naive %",
                    "shm %", "ref %", "full s", "red. s", "ref s");
    for (const Case& c : cases) {
        const SurfaceMesh mesh(c.mesh, c.name);
        SurfaceWindingNumbers swn(mesh);
        SwnOptions full = defaults, reduced = defaults;
        full.residual = SwnResidual::Full;
        reduced.residual = SwnResidual::Reduced;
        const SwnResult rf = swn.solve(c.curves, full);
        const SwnResult rr = swn.solve(c.curves, reduced);
        SignedHeatSurface shm(mesh);
        const std::vector<int> shm_l = shm_labels(mesh, shm.solve(c.curves).phi);
        std::map<std::string, double> err;
        err["swn-full"] = 100 * mislabeled_area(mesh, rf.labels, c.truth, true);
        err["swn-reduced"] = 100 * mislabeled_area(mesh, rr.labels, c.truth, true);
        err["naive-u"] = 100 * mislabeled_area(mesh, rf.naive_labels, c.truth, true);
        err["shm-sign"] = 100 * mislabeled_area(mesh, shm_l, c.truth, true);
        full_vs_reduced.add(100 * mislabeled_area(mesh, rr.labels, rf.labels, true));
        if (!rf.simply_connected && rf.lp_objective > 0 && defaults.curve_weight > 0) {
            // The reduced program is the full one restricted: its optimum is never lower — with
            // one curve weight for both (--curve-weight; by default each has its own, and the
            // costs do not compare).
            const double gap = (rr.lp_objective - rf.lp_objective) / rf.lp_objective;
            objective_gap.add(100 * gap);
            equal_optimum += gap < 1e-6;
            ++programs;
        }
        t_full.add(rf.seconds_residual);
        t_reduced.add(rr.seconds_residual);
        double ref_seconds = NAN;
        if (!reference.empty() && c.on_edges) {
            if (const auto ref = run_reference(reference, c, work, ref_seconds)) {
                err["reference"] = 100 * mislabeled_area(mesh, *ref, c.truth, true);
                t_ref.add(ref_seconds);
            }
        }
        const std::string mesh_name = c.name.substr(0, c.name.find('/'));
        const std::string damage = c.name.substr(c.name.rfind('/') + 1);
        const std::string where = c.on_edges ? "edges" : "faces";
        for (const auto& [m, e] : err) {
            by_group["all"][m].add(e);
            by_group[mesh_name][m].add(e);
            by_group[damage][m].add(e);
            by_group["on " + where][m].add(e);
        }
        if (!quiet) {
            auto cell = [&](const char* m) {
                char s[16];
                if (err.count(m)) std::snprintf(s, sizeof(s), "%9.2f", err[m]);
                else std::snprintf(s, sizeof(s), "%9s", "-");
                return std::string(s);
            };
            std::printf("%-34s %7zu %s %s %s %s %s   %7.3f %7.3f %7.2f\n", c.name.c_str(), mesh.face_count(),
                        cell("swn-full").c_str(), cell("swn-reduced").c_str(), cell("naive-u").c_str(),
                        cell("shm-sign").c_str(), cell("reference").c_str(), rf.seconds_residual, rr.seconds_residual,
                        ref_seconds);
            std::fflush(stdout);
        }
    }
    std::printf("\nMislabeled area, %% of the surface (up to a global integer shift): mean / median / max over %zu cases\n",
                cases.size());
    std::printf("%-14s %6s", "group", "cases");
    for (const std::string& m : methods) std::printf(" %22s", m.c_str());
    std::printf("\n");
    for (const char* g : {"all", "sphere", "torus", "double-torus", "on edges", "on faces", "cut0%", "cut30%", "cut50%"}) {
        if (!by_group.count(g)) continue;
        std::printf("%-14s %6zu", g, by_group[g]["swn-full"].v.size());
        for (const std::string& m : methods) {
            const Stats& s = by_group[g][m];
            if (s.v.empty()) std::printf(" %22s", "-");
            else std::printf("   %6.2f /%6.2f /%6.2f", s.mean(), s.median(), s.max());
        }
        std::printf("\n");
    }
    std::printf("\nfull vs reduced program: labels differ on %.3f %% of the area on average (max %.3f %%)\n",
                full_vs_reduced.mean(), full_vs_reduced.max());
    if (programs)
        std::printf("reduced program's optimum above the full one's by %.3f %% on average (max %.3f %%); equal in %zu of %zu\n",
                    objective_gap.mean(), objective_gap.max(), equal_optimum, programs);
    std::printf("residual step: full %.3f s, reduced %.4f s on average (%.0fx)", t_full.mean(), t_reduced.mean(),
                t_full.mean() / t_reduced.mean());
    if (!t_ref.v.empty()) std::printf("; reference whole run %.2f s on average", t_ref.mean());
    std::printf("\n");
    return 0;
}

// ---- timing --------------------------------------------------------------------------------

int timing(const std::vector<int>& sizes, int clp_max) {
    std::printf("Double torus, a broken bounding loop (30 %% cut) and broken loops around both handles; seconds\n");
    std::printf("%6s %8s %8s %8s %8s %9s %9s %7s %9s %9s %9s\n", "grid", "faces", "jump", "hodge", "full", "reduced",
                "full/red", "labels", "total", "clp", "clp/net");
    for (int n : sizes) {
        const PolygonMesh m = shapes::double_torus_mesh(n);
        const SurfaceMesh mesh(m, "double torus");
        std::vector<double> f(mesh.vertex_count());
        for (std::size_t v = 0; v < f.size(); ++v) f[v] = (vertex(m, std::uint32_t(v)) - Eigen::Vector3d(-0.85, 0.3, 0.1)).norm() - 0.45;
        SurfaceSources src;
        src.curves = level_set_curves(mesh, f, 0);
        for (const Eigen::Vector3d& hole : {Eigen::Vector3d(-0.425, 0, 0), Eigen::Vector3d(0.425, 0, 0)})
            for (SurfaceCurve& c : handle_loop(mesh, m, hole, hole.x() < 0 ? 2.6 : 0.4, false, false))
                src.curves.push_back(std::move(c));
        src = damage(src, {0.3, 3, 0}, 5);
        SurfaceWindingNumbers swn(mesh);
        SwnOptions full, reduced, clp;
        full.residual = clp.residual = SwnResidual::Full;
        reduced.residual = SwnResidual::Reduced;
        clp.solver = SwnSolver::Clp;
        const SwnResult rf = swn.solve(src, full);
        const SwnResult rr = swn.solve(src, reduced);
        const double agree = 100 * (1 - mislabeled_area(mesh, rr.labels, rf.labels, false));
        char clp_s[32] = "-", ratio[32] = "-";
        if (n <= clp_max) {
            const SwnResult rc = swn.solve(src, clp);
            std::snprintf(clp_s, sizeof(clp_s), "%9.2f", rc.seconds_residual);
            std::snprintf(ratio, sizeof(ratio), "%8.0fx", rc.seconds_residual / rf.seconds_residual);
        }
        std::printf("%6d %8zu %8.3f %8.3f %8.3f %9.4f %8.0fx %6.2f%% %9.3f %9s %9s\n", n, mesh.face_count(), rf.seconds_jump,
                    rf.seconds_hodge, rf.seconds_residual, rr.seconds_residual,
                    rf.seconds_residual / rr.seconds_residual, agree, rf.seconds_total, clp_s, ratio);
        std::fflush(stdout);
    }
    std::printf("(jump: the jump Laplace equation solved twice, first factorization included; labels: area where "
                "full and reduced agree)\n");
    return 0;
}

// ---- broken loops ------------------------------------------------------------------------------

/// The torus' outer equator along mesh edges (torus_mesh's minor rings are at angles 2πj/m, so
/// j = 0 is on the edges): a loop around the hole.
std::vector<SurfaceCurve> hole_loop(const PolygonMesh& m, bool reverse) {
    std::vector<int> below(m.face_count());
    for (std::size_t f = 0; f < m.face_count(); ++f) {
        const std::uint32_t* v = face(m, f);
        below[f] = (vertex(m, v[0]) + vertex(m, v[1]) + vertex(m, v[2])).z() < 0;
    }
    std::vector<SurfaceCurve> loops = region_boundary(m, below, [](const Eigen::Vector3d& x) { return std::hypot(x.x(), x.y()) > 0.5; });
    if (reverse)
        for (SurfaceCurve& k : loops) std::reverse(k.nodes.begin(), k.nodes.end());
    return loops;
}

/// One case of the broken-loops class: a torus, a small disk region's boundary and a loop around
/// the tube (or the hole) (random side, orientation), both broken, on mesh edges.
Case broken_loops_case(int seed, double cut, bool around_hole = false) {
    std::mt19937_64 rng(std::uint64_t(977 * seed + 13));
    std::uniform_real_distribution<double> u(0, 1);
    const int n = 48 + 12 * seed;
    Case c;
    c.mesh = shapes::torus_mesh(n, n / 3);
    c.on_edges = true;
    const SurfaceMesh mesh(c.mesh);
    for (int attempt = 0; attempt < 100; ++attempt) {
        // A disk around a random point of the surface, radius 0.12–0.25 (the tube's radius is 0.2).
        const double a = 2 * kPi * u(rng), b = 2 * kPi * u(rng), radius = 0.12 + 0.13 * u(rng);
        const Eigen::Vector3d center((0.5 + 0.2 * std::cos(b)) * std::cos(a), (0.5 + 0.2 * std::cos(b)) * std::sin(a),
                                     0.2 * std::sin(b));
        c.truth.assign(c.mesh.face_count(), 0);
        for (std::size_t f = 0; f < c.truth.size(); ++f) {
            const std::uint32_t* v = face(c.mesh, f);
            c.truth[f] = ((vertex(c.mesh, v[0]) + vertex(c.mesh, v[1]) + vertex(c.mesh, v[2])) / 3 - center).norm() < radius;
        }
        if (all_disks(c.mesh, c.truth, 1) && all_disks(c.mesh, c.truth, 1)) break;
    }
    SurfaceSources src;
    src.curves = region_boundary(c.mesh, c.truth, [](const Eigen::Vector3d&) { return true; });
    std::set<std::pair<std::uint32_t, std::uint32_t>> used;
    for (const SurfaceCurve& k : src.curves)
        for (std::size_t i = 0; i + 1 < k.nodes.size(); ++i) used.insert(std::minmax(k.nodes[i].index, k.nodes[i + 1].index));
    const bool reverse = u(rng) < 0.5;
    for (int attempt = 0; attempt < 50; ++attempt) {
        const double theta = 2 * kPi * u(rng);
        const std::vector<SurfaceCurve> loops =
            around_hole ? hole_loop(c.mesh, reverse) : handle_loop(mesh, c.mesh, Eigen::Vector3d::Zero(), theta, true, reverse);
        bool shares = false;
        for (const SurfaceCurve& k : loops)
            for (std::size_t i = 0; i + 1 < k.nodes.size(); ++i)
                shares = shares || used.count(std::minmax(k.nodes[i].index, k.nodes[i + 1].index));
        if (shares && attempt + 1 < 50) continue;
        src.curves.insert(src.curves.end(), loops.begin(), loops.end());
        break;
    }
    c.curves = damage(src, {cut, 3, 1}, std::uint64_t(seed));
    char name[64];
    std::snprintf(name, sizeof(name), "torus %dx%d, seed %d", n, n / 3, seed);
    c.name = name;
    return c;
}

int broken_loops(int seeds, double cut, bool around_hole, const std::string& reference, std::string work) {
    if (work.empty()) work = std::filesystem::temp_directory_path().string() + "/gsd-swn-bench";
    std::filesystem::create_directories(work);
    std::printf("%-26s %7s %10s %10s %10s %10s %10s\n", "case", "faces", "reduced %", "full %", "no close %", "ref %",
                "naive %");
    Stats reduced, full, closed, ref;
    for (int seed = 1; seed <= seeds; ++seed) {
        const Case c = broken_loops_case(seed, cut, around_hole);
        const SurfaceMesh mesh(c.mesh, c.name);
        SurfaceWindingNumbers swn(mesh);
        SwnOptions o;
        const SwnResult rr = swn.solve(c.curves, o);
        o.residual = SwnResidual::Full;
        const SwnResult rf = swn.solve(c.curves, o);
        const double er = 100 * mislabeled_area(mesh, rr.labels, c.truth, true);
        const double ef = 100 * mislabeled_area(mesh, rf.labels, c.truth, true);
        SwnOptions oc;
        oc.close_gaps = false;
        const double ec = 100 * mislabeled_area(mesh, swn.solve(c.curves, oc).labels, c.truth, true);
        reduced.add(er);
        full.add(ef);
        closed.add(ec);
        double seconds = 0, eref = NAN;
        if (!reference.empty())
            if (const auto labels = run_reference(reference, c, work, seconds)) {
                eref = 100 * mislabeled_area(mesh, *labels, c.truth, true);
                ref.add(eref);
            }
        std::printf("%-26s %7zu %10.2f %10.2f %10.2f %10.2f %10.2f\n", c.name.c_str(), mesh.face_count(), er, ef, ec, eref,
                    100 * mislabeled_area(mesh, rr.naive_labels, c.truth, true));
        std::fflush(stdout);
    }
    std::printf("%-26s %7s %10.2f %10.2f %10.2f %10.2f\n", "mean", "", reduced.mean(), full.mean(), closed.mean(), ref.mean());
    return 0;
}

// ---- thesis §7.1: level sets of Laplacian eigenfunctions, with offsets, half deleted ---------

/// A smooth random bend: every vertex moved along three plane waves of wavelength about the
/// shape's size, by up to `amplitude` × its size. The methods are intrinsic: what matters is that
/// the triangles and the eigenfunctions change.
PolygonMesh bent(PolygonMesh m, std::mt19937_64& rng, double amplitude) {
    std::normal_distribution<double> n(0, 1);
    std::uniform_real_distribution<double> u(0, 1);
    const double size = (m.vertices.colwise().maxCoeff() - m.vertices.colwise().minCoeff()).norm();
    for (int wave = 0; wave < 3; ++wave) {
        const double kx = n(rng), ky = n(rng), kz = n(rng), dx = n(rng), dy = n(rng), dz = n(rng);
        const Eigen::Vector3d k = Eigen::Vector3d(kx, ky, kz).normalized() * (2 * kPi / size) * (1 + u(rng));
        const Eigen::Vector3d d = Eigen::Vector3d(dx, dy, dz).normalized() * amplitude * size / 3;
        const double phase = 2 * kPi * u(rng);
        for (Eigen::Index v = 0; v < m.vertices.rows(); ++v) {
            const Eigen::Vector3d x = m.vertices.row(v).transpose();
            m.vertices.row(v) += (d * std::sin(k.dot(x) + phase)).transpose();
        }
    }
    return m;
}

/// The §7.1 meshes: closed, about 5k vertices, genus 0 and 1 in turn, contoured from an SDF
/// (irregular triangles; not from shapes with flat sides, where contouring leaves triangles of zero
/// area) or parametric grids (regular ones), each bent at random (seed `index`; the blob more).
PolygonMesh section71_mesh(int index, std::string& name) {
    std::mt19937_64 rng(std::uint64_t(7919 * index + 3));
    struct Kind {
        const char* name;
        std::function<PolygonMesh()> make;
    };
    const std::array<Kind, 8> kinds{{
        {"sphere, contoured", [] { return shapes::mesh(*shapes::sphere(Eigen::Vector3d::Zero(), 0.5), 25); }},
        {"torus grid", [] { return shapes::torus_mesh(118, 42); }},
        {"capsule, contoured", [] { return shapes::mesh(*shapes::by_name("capsule"), 26); }},
        {"torus, contoured", [] { return shapes::mesh(*shapes::by_name("torus"), 23); }},
        {"blob, contoured", [] { return shapes::mesh(*shapes::sphere(Eigen::Vector3d::Zero(), 0.5), 24); }},
        {"thin torus grid", [] { return shapes::torus_mesh(160, 32, 0.5, 0.125); }},
        {"icosphere", [] { return shapes::icosphere(4); }},
        {"fat torus grid", [] { return shapes::torus_mesh(100, 50, 0.5, 0.3); }},
    }};
    const Kind& k = kinds[std::size_t(index) % kinds.size()];
    name = std::string(k.name) + " #" + std::to_string(index);
    return bent(k.make(), rng, index % kinds.size() == 4 ? 0.4 : 0.15);
}

/// Faces that share a vertex with a face of `region` (grow) or whose vertices all lie only on
/// faces of `region` (shrink): the region one ring of triangles larger or smaller. Their
/// boundaries are the boundaries of the triangle strips along the region's own (thesis §7.1).
std::vector<int> offset_region(const PolygonMesh& m, const std::vector<int>& region, bool grow) {
    std::vector<std::uint8_t> touches(std::size_t(m.vertices.rows()), 0);  // vertex on a face of the other side
    for (std::size_t f = 0; f < m.face_count(); ++f)
        if (region[f] == (grow ? 1 : 0))
            for (int k = 0; k < 3; ++k) touches[face(m, f)[k]] = 1;
    std::vector<int> out(region);
    for (std::size_t f = 0; f < m.face_count(); ++f) {
        bool near = false;
        for (int k = 0; k < 3; ++k) near = near || touches[face(m, f)[k]];
        if (near) out[f] = grow ? 1 : 0;
    }
    return out;
}

/// About `fraction` of each curve's pieces deleted in 2–6 gaps of random lengths at random places
/// (the kept runs random too).
SurfaceSources delete_intervals(const SurfaceSources& src, double fraction, std::mt19937_64& rng) {
    SurfaceSources out;
    for (const SurfaceCurve& c : src.curves) {
        const std::size_t pieces = c.nodes.size() - 1;
        const std::size_t gaps = std::clamp<std::size_t>(2 + rng() % 5, 1, std::max<std::size_t>(1, pieces / 4));
        const auto cut = std::size_t(std::lround(fraction * double(pieces)));
        // Random compositions of `cut` and `pieces − cut` into `gaps` positive parts.
        auto split = [&](std::size_t total) {
            std::vector<std::size_t> marks{0, total};
            for (std::size_t g = 1; g < gaps; ++g) marks.push_back(total > gaps ? 1 + rng() % (total - 1) : g);
            std::sort(marks.begin(), marks.end());
            std::vector<std::size_t> parts;
            for (std::size_t g = 0; g + 1 < marks.size(); ++g) parts.push_back(marks[g + 1] - marks[g]);
            return parts;
        };
        const std::vector<std::size_t> removed = split(cut), kept = split(pieces - cut);
        std::vector<std::uint8_t> drop(pieces, 0);
        std::size_t at = rng() % pieces;
        for (std::size_t g = 0; g < gaps; ++g) {
            for (std::size_t i = 0; i < removed[g]; ++i) drop[at++ % pieces] = 1;
            at += kept[g];
        }
        SurfaceCurve run;
        run.is_signed = c.is_signed;
        for (std::size_t i = 0; i < pieces; ++i) {
            if (!drop[i]) {
                if (run.nodes.empty()) run.nodes.push_back(c.nodes[i]);
                run.nodes.push_back(c.nodes[i + 1]);
            } else if (!run.nodes.empty()) {
                out.curves.push_back(std::move(run));
                run.nodes.clear();
            }
        }
        if (!run.nodes.empty()) out.curves.push_back(std::move(run));
    }
    return out;
}

/// Case `which` (0–4) on mesh `index`: the region below a random level (30–70 % of the vertices)
/// of the which-th lowest nonconstant Laplacian eigenfunction is the truth; its boundary along
/// mesh edges plus the boundary of the region one ring larger or smaller (same orientation: a
/// second, parallel curve) is the curve, about half of it deleted at random intervals.
Case section71_case(int index, int which, const PolygonMesh& m, const std::string& mesh_name,
                    const Eigen::MatrixXd& eigenfunctions) {
    std::mt19937_64 rng(std::uint64_t(104729 * index + 31 * which + 5));
    std::uniform_real_distribution<double> u(0, 1);
    const Eigen::VectorXd phi = eigenfunctions.col(which + 1);
    std::vector<double> sorted(phi.data(), phi.data() + phi.size());
    std::sort(sorted.begin(), sorted.end());
    const double level = sorted[std::size_t((0.3 + 0.4 * u(rng)) * double(sorted.size() - 1))];
    Case c;
    c.mesh = m;
    c.on_edges = true;
    c.truth.resize(m.face_count());
    for (std::size_t f = 0; f < m.face_count(); ++f) {
        const std::uint32_t* v = face(m, f);
        c.truth[f] = phi[v[0]] + phi[v[1]] + phi[v[2]] < 3 * level;
    }
    const bool grow = u(rng) < 0.5;
    SurfaceSources full;
    full.curves = region_boundary(m, c.truth, [](const Eigen::Vector3d&) { return true; });
    for (SurfaceCurve& k : region_boundary(m, offset_region(m, c.truth, grow), [](const Eigen::Vector3d&) { return true; }))
        full.curves.push_back(std::move(k));
    c.curves = delete_intervals(full, 0.5, rng);
    char name[128];
    std::snprintf(name, sizeof(name), "%s, eigenfunction %d", mesh_name.c_str(), which + 1);
    c.name = name;
    return c;
}

struct Section71Args {
    int meshes = 8;
    SwnOptions options;
    std::string reference, work;
    bool quiet = false;
};

int section71(Section71Args args) {
    if (args.work.empty()) args.work = std::filesystem::temp_directory_path().string() + "/gsd-swn-bench";
    std::filesystem::create_directories(args.work);
    const std::vector<std::string> methods = {"swn", "swn best", "shm", "shm bounding", "reference", "ref best"};
    std::map<std::string, std::map<std::string, Stats>> by_group;  // group → method → mislabeled %
    std::map<std::string, Stats> seconds;
    if (!args.quiet) {
        std::printf("%-44s %6s", "case", "faces");
        for (const std::string& m : methods) std::printf(" %12s", (m + " %").c_str());
        std::printf("\n");
    }
    for (int index = 0; index < args.meshes; ++index) {
        std::string mesh_name;
        const PolygonMesh m = section71_mesh(index, mesh_name);
        const Eigen::MatrixXd eigenfunctions = bench::laplace_eigenfunctions(m, 6);
        const SurfaceMesh mesh(m, mesh_name);
        const bool genus0 = mesh.summary().euler_characteristic == 2;
        SurfaceWindingNumbers swn(mesh);
        SignedHeatSurface shm(mesh);
        for (int which = 0; which < 5; ++which) {
            const Case c = section71_case(index, which, m, mesh_name, eigenfunctions);
            std::map<std::string, double> err;
            auto t0 = Clock::now();
            const SwnResult r = swn.solve(c.curves, args.options);
            seconds["swn"].add(since(t0));
            err["swn"] = 100 * mislabeled_area(mesh, inside_by_curve_levels(m, r.labels, c.curves), c.truth, false);
            err["swn best"] = 100 * best_threshold_error(mesh, r.labels, c.truth);
            t0 = Clock::now();
            err["shm"] = 100 * mislabeled_area(mesh, shm_labels(mesh, shm.solve(c.curves).phi), c.truth, false);
            seconds["shm"].add(since(t0));
            if (!r.bounding_curves.curves.empty())  // gsd shm surface --filter-nonbounding's sign
                err["shm bounding"] =
                    100 * mislabeled_area(mesh, shm_labels(mesh, shm.solve(r.bounding_curves).phi), c.truth, false);
            if (!args.reference.empty()) {
                double s = 0;
                if (const auto ref = run_reference(args.reference, c, args.work, s)) {
                    err["reference"] = 100 * mislabeled_area(mesh, inside_by_curve_levels(m, *ref, c.curves), c.truth, false);
                    err["ref best"] = 100 * best_threshold_error(mesh, *ref, c.truth);
                    seconds["reference"].add(s);
                }
            }
            for (const auto& [method, e] : err) {
                by_group["all"][method].add(e);
                by_group[genus0 ? "genus 0" : "genus 1"][method].add(e);
            }
            if (!args.quiet) {
                std::printf("%-44s %6zu", c.name.c_str(), m.face_count());
                for (const std::string& method : methods)
                    if (err.count(method)) std::printf(" %12.2f", err[method]);
                    else std::printf(" %12s", "-");
                std::printf("\n");
                std::fflush(stdout);
            }
        }
    }
    std::printf("\nMislabeled area, %% of the surface, inside/outside: mean / median / max, and cases above 50 %%\n");
    std::printf("%-8s %5s", "group", "cases");
    for (const std::string& m : methods) std::printf(" %26s", m.c_str());
    std::printf("\n");
    for (const char* g : {"all", "genus 0", "genus 1"}) {
        if (!by_group.count(g)) continue;
        std::printf("%-8s %5zu", g, by_group[g]["swn"].v.size());
        for (const std::string& m : methods) {
            const Stats& s = by_group[g][m];
            if (s.v.empty()) {
                std::printf(" %26s", "-");
                continue;
            }
            const auto above = std::count_if(s.v.begin(), s.v.end(), [](double x) { return x > 50; });
            std::printf("   %5.1f /%5.1f /%5.1f  >50:%2ld", s.mean(), s.median(), s.max(), long(above));
        }
        std::printf("\n");
    }
    std::printf("\nseconds per case (mean):");
    for (const auto& [m, s] : seconds) std::printf(" %s %.3f", m.c_str(), s.mean());
    std::printf("\n");
    return 0;
}

/// PREFIX.obj, PREFIX.txt and PREFIX.truth.npy of one case.
int write_files(const Case& c, const std::string& prefix) {
    io::write_mesh(prefix + ".obj", c.mesh);
    write_surface_curves(prefix + ".txt", c.curves);
    std::vector<std::int32_t> truth(c.truth.begin(), c.truth.end());
    io::write_npy(prefix + ".truth.npy", {truth.size()}, truth);
    std::printf("wrote %s.obj, .txt, .truth.npy (%s)\n", prefix.c_str(), c.name.c_str());
    return 0;
}

int write_case(const std::string& name, const std::string& prefix, const MeshSizes& sizes) {
    if (name.rfind("broken-loops/", 0) == 0) {  // broken-loops/SEED[/CUT]
        const std::string rest = name.substr(13);
        const double cut = rest.find('/') == std::string::npos ? 0.3 : std::atof(rest.substr(rest.find('/') + 1).c_str());
        return write_files(broken_loops_case(std::atoi(rest.c_str()), cut), prefix);
    }
    if (name.rfind("section71/", 0) == 0) {  // section71/MESH/EIGENFUNCTION (1–5)
        const int index = std::atoi(name.substr(10).c_str());
        const int which = std::atoi(name.substr(name.rfind('/') + 1).c_str()) - 1;
        if (index < 0 || which < 0 || which > 4) throw std::runtime_error("section71/MESH/EIGENFUNCTION: MESH ≥ 0, EIGENFUNCTION 1–5");
        std::string mesh_name;
        const PolygonMesh m = section71_mesh(index, mesh_name);
        return write_files(section71_case(index, which, m, mesh_name, bench::laplace_eigenfunctions(m, 6)), prefix);
    }
    const int index = std::atoi(name.substr(name.find('/') + 1).c_str());
    for (const Case& c : make_cases(index + 1, sizes))
        if (c.name == name) return write_files(c, prefix);
    std::fprintf(stderr, "no case named %s\n", name.c_str());
    return 2;
}

}  // namespace

int main(int argc, char** argv) {
    CLI::App app{"Surface Winding Numbers: accuracy on a synthetic benchmark, and timing (scripts/bench.sh swn)"};
    app.require_subcommand(1);
    // The meshes' resolutions, for accuracy and write (at least 12: torus_mesh(N, N/3)).
    auto add_sizes = [](CLI::App* c, MeshSizes& s) {
        c->add_option("--torus", s.torus, "the torus's resolution")->check(CLI::Range(12, 100000))->capture_default_str();
        c->add_option("--double-torus", s.double_torus, "the double torus's resolution")
            ->check(CLI::Range(12, 100000))->capture_default_str();
    };
    AccuracyArgs acc;
    CLI::App* a = app.add_subcommand("accuracy", "mislabeled area of SWN (full, reduced), naive rounding, SHM's sign, a reference");
    a->add_option("--cases", acc.per, "random functions per mesh")->check(CLI::PositiveNumber)->capture_default_str();
    a->add_option("--only", acc.only, "the cases on one mesh")->check(CLI::IsMember({"sphere", "torus", "double-torus"}));
    add_sizes(a, acc.sizes);
    a->add_option("--curve-weight", acc.defaults.curve_weight, "SwnOptions::curve_weight")->capture_default_str();
    a->add_flag("--close-gaps,!--no-close-gaps", acc.defaults.close_gaps, "SwnOptions::close_gaps")->capture_default_str();
    a->add_option("--reference", acc.reference, "a program `REF MESH.obj CURVES.txt -o PREFIX` writing PREFIX.labels.npy");
    a->add_option("--work", acc.work, "a folder for the reference's files (default: a temporary one)");
    a->add_flag("--quiet", acc.quiet, "the summary only");
    std::vector<int> timing_sizes{32, 48, 64, 96, 128};
    int clp_max = 48;
    CLI::App* t = app.add_subcommand("timing", "time per step and full vs reduced program vs mesh size; the network solver vs CLP");
    t->add_option("--sizes", timing_sizes, "double torus resolutions")->delimiter(',')->check(CLI::Range(4, 100000))->capture_default_str();
    t->add_option("--clp-max", clp_max, "the largest size CLP runs on")->capture_default_str();
    std::string case_name, prefix;
    MeshSizes write_sizes;
    CLI::App* w = app.add_subcommand("write", "one accuracy case as PREFIX.obj, PREFIX.txt and PREFIX.truth.npy");
    w->add_option("CASE", case_name, "a name from the accuracy table")->required();
    w->add_option("PREFIX", prefix, "where to write")->required();
    add_sizes(w, write_sizes);
    int seeds = 5;
    std::string bl_reference, bl_work;
    CLI::App* bl = app.add_subcommand("broken-loops", "tori with a broken small loop and a broken loop around the tube");
    bl->add_option("--seeds", seeds, "cases (seeds 1…N)")->check(CLI::Range(1, 1000))->capture_default_str();
    double bl_cut = 0.3;
    bl->add_option("--cut", bl_cut, "share of each loop cut away (in 3 gaps)")->check(CLI::Range(0.0, 0.9))->capture_default_str();
    std::string bl_around = "tube";
    bl->add_option("--around", bl_around, "the nonbounding loop goes around the tube or the hole (the outer equator)")
        ->check(CLI::IsMember({"tube", "hole"}))->capture_default_str();
    bl->add_option("--reference", bl_reference, "a program `REF MESH.obj CURVES.txt -o PREFIX` writing PREFIX.labels.npy");
    bl->add_option("--work", bl_work, "a folder for the reference's files (default: a temporary one)");
    Section71Args s71;
    CLI::App* th = app.add_subcommand("section71", "the thesis' §7.1 comparison: level sets of Laplacian eigenfunctions "
                                                   "with offsets, half deleted; inside/outside of SWN, SHM's sign, a reference");
    th->add_option("--meshes", s71.meshes, "meshes (genus 0 and 1 in turn), five cases each")->check(CLI::Range(1, 1000))->capture_default_str();
    th->add_option("--reference", s71.reference, "a program `REF MESH.obj CURVES.txt -o PREFIX` writing PREFIX.labels.npy");
    th->add_option("--work", s71.work, "a folder for the reference's files (default: a temporary one)");
    th->add_flag("--quiet", s71.quiet, "the summary only");
    th->add_flag("--close-gaps,!--no-close-gaps", s71.options.close_gaps, "SwnOptions::close_gaps")->capture_default_str();
    CLI11_PARSE(app, argc, argv);
    try {
        if (*a) return accuracy(acc);
        if (*bl) return broken_loops(seeds, bl_cut, bl_around == "hole", bl_reference, bl_work);
        if (*th) return section71(s71);
        if (*t) return timing(timing_sizes, clp_max);
        return write_case(case_name, prefix, write_sizes);
    } catch (const std::exception& e) {
        std::fprintf(stderr, "gsd-swn-bench: %s\n", e.what());
        return 1;
    }
}
