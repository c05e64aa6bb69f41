// The march of any gsd::Field on the CPU, every ray of a band together: one evaluation of the
// field per step over all the rays still marching, then the bisections together, then ∇φ at
// the hits together. For fields whose evaluation is a call over many points — composites of
// the field algebra, a mesh's exact distance — where a call per point per step would cost more
// than the sums. The arithmetic of each ray is march_ray's (render.cpp); only φ comes in float32,
// as every Field gives it.
#include "render/render.hpp"

#include "core/uninitialized.hpp"
#include "core/threads.hpp"

#include <algorithm>
#include <cmath>

namespace gsd::render {

namespace {

struct Ray {
    Eigen::Vector3d o, d;  // o: where the ray enters the box
    double entry = 0, span = 0, t = 0, phi = 0;
    double a = 0, b = 0, pa = 0;  // the bisection's bracket
    long pixel = 0;
    bool fresh = false;  // its next sample follows a skip through empty cells
};
// A band's rays: tens of MB, in huge pages where the system offers them (uninitialized.hpp:
// 4 KiB pages cost a fault each at first touch, 0.1 s for a 320×240 picture at 2×2 rays a
// pixel on the 2-core machine).
using Rays = std::vector<Ray, detail::UninitializedAllocator<Ray>>;

// φ at o + t·d for the listed rays (t_of(k, ray): the t of the list's k-th), in one evaluation:
// on the host when they are few and the field offers it (`device` then stays as it was).
template <class T>
std::vector<float> phi_at(const PointEvaluator& field, const Rays& rays, const std::vector<std::size_t>& which,
                          T&& t_of, std::string& device) {
    Points p(Eigen::Index(which.size()), 3);
#pragma omp parallel for schedule(static)
    for (std::ptrdiff_t k = 0; k < std::ptrdiff_t(which.size()); ++k) {
        const Ray& r = rays[which[std::size_t(k)]];
        p.row(Eigen::Index(k)) = (r.o + t_of(std::size_t(k), r) * r.d).transpose();
    }
    if (which.empty()) return {};
    const auto& evaluate = field.for_points(which.size());
    FieldValues v = evaluate(p, false);
    if (&evaluate == &field.evaluate) device = v.device;  // not the host evaluator's "cpu"
    return std::move(v.phi);
}

// ∇φ at the points: the field's own, or central differences of step h.
std::vector<Eigen::Vector3d> gradients_at(const PointEvaluator& field, const Points& x, double h) {
    std::vector<Eigen::Vector3d> g(std::size_t(x.rows()));
    if (x.rows() == 0) return g;
    if (field.has_gradient) {
        const FieldValues v = field.for_points(std::size_t(x.rows()))(x, true);
        for (std::size_t i = 0; i < g.size(); ++i) g[i] = {v.gradient[3 * i], v.gradient[3 * i + 1], v.gradient[3 * i + 2]};
        return g;
    }
    Points p(6 * x.rows(), 3);
    for (Eigen::Index i = 0; i < x.rows(); ++i)
        for (int a = 0; a < 3; ++a)
            for (int s = 0; s < 2; ++s) p.row(6 * i + 2 * a + s) = x.row(i) + (s ? -h : h) * Eigen::RowVector3d::Unit(a);
    const FieldValues v = field.evaluate(p, false);
    for (std::size_t i = 0; i < g.size(); ++i)
        for (int a = 0; a < 3; ++a) g[i][a] = (double(v.phi[6 * i + 2 * std::size_t(a)]) - v.phi[6 * i + 2 * std::size_t(a) + 1]) / (2 * h);
    return g;
}

// The march of a band's listed rays: those still marching, those bracketing a crossing, and
// the hits found (ray, t).
struct BandMarch {
    const PointEvaluator& field;
    Rays& rays;
    const March& m;
    std::string& device;
    std::vector<std::size_t> marching, bisecting;
    std::vector<std::pair<std::size_t, double>> found;

    // φ where each ray starts; a ray starting on the surface has hit it.
    void start() {
        const std::vector<float> phi = phi_at(field, rays, marching, [](std::size_t, const Ray& r) { return r.t; }, device);
        std::vector<std::size_t> next;
        for (std::size_t i = 0; i < marching.size(); ++i) {
            Ray& r = rays[marching[i]];
            r.phi = phi[i];
            if (std::abs(r.phi) < m.hit_eps) found.push_back({marching[i], r.t});
            else next.push_back(marching[i]);
        }
        marching.swap(next);
    }

    // One step of every marching ray (past empty cells where it can skip); those past the box's
    // far side are misses.
    void step() {
        std::vector<double> step_to(marching.size());
        std::vector<char> goes_on(marching.size());
#pragma omp parallel for schedule(static)
        for (std::size_t i = 0; i < marching.size(); ++i) {
            Ray& r = rays[marching[i]];
            double t = r.t + std::max(m.step_scale * std::abs(r.phi), m.min_step);
            const double stepped = t;
            goes_on[i] = t <= r.span && skip_empty(m, r.o, r.d, r.span, t, r.phi < 0 ? -1 : 1);
            r.fresh = t != stepped;
            step_to[i] = t;
        }
        std::vector<std::size_t> next;
        std::vector<double> tn;
        for (std::size_t i = 0; i < marching.size(); ++i)
            if (goes_on[i]) {
                next.push_back(marching[i]);
                tn.push_back(step_to[i]);
            }
        const std::vector<float> pn = phi_at(field, rays, next, [&](std::size_t k, const Ray&) { return tn[k]; }, device);
        marching.clear();
        for (std::size_t i = 0; i < next.size(); ++i) take_step(next[i], tn[i], pn[i]);
    }

    // Ray k sampled φ = pn at tn.
    void take_step(std::size_t k, double tn, float pn) {
        Ray& r = rays[k];
        if (r.fresh && std::abs(pn) < m.hit_eps) {  // after a skip: a fresh start at tn
            found.push_back({k, tn});
        } else if (r.fresh) {
            r.t = tn;
            r.phi = pn;
            marching.push_back(k);
        } else if ((pn < 0) != (r.phi < 0)) {  // crossed within the step: bisect [t, tn]
            r.a = r.t;
            r.b = tn;
            r.pa = r.phi;
            bisecting.push_back(k);
        } else if (std::abs(pn) < m.hit_eps) {
            found.push_back({k, tn});
        } else {
            r.t = tn;
            r.phi = pn;
            marching.push_back(k);
        }
    }

    // The crossings' brackets halved m.bisection times; their midpoints are hits.
    void bisect() {
        for (int k = 0; k < m.bisection && !bisecting.empty(); ++k) {
            const std::vector<float> pm = phi_at(field, rays, bisecting, [](std::size_t, const Ray& r) { return 0.5 * (r.a + r.b); }, device);
            for (std::size_t i = 0; i < bisecting.size(); ++i) {
                Ray& r = rays[bisecting[i]];
                const double mid = 0.5 * (r.a + r.b);
                if ((pm[i] < 0) == (r.pa < 0)) {
                    r.a = mid;
                    r.pa = pm[i];
                } else {
                    r.b = mid;
                }
            }
        }
        for (std::size_t k : bisecting) found.push_back({k, 0.5 * (rays[k].a + rays[k].b)});
        bisecting.clear();
    }

    // Each hit's t (from the camera) and ∇φ into hits[4·pixel ...].
    void write_hits(std::vector<float>& hits) const {
        Points at(Eigen::Index(found.size()), 3);
        for (std::size_t i = 0; i < found.size(); ++i) {
            const Ray& r = rays[found[i].first];
            at.row(Eigen::Index(i)) = (r.o + found[i].second * r.d).transpose();
        }
        const std::vector<Eigen::Vector3d> g = gradients_at(field, at, m.hit_eps);
        for (std::size_t i = 0; i < found.size(); ++i) {
            const Ray& r = rays[found[i].first];
            float* h = &hits[std::size_t(4 * r.pixel)];
            h[0] = float(r.entry + found[i].second);
            for (int a = 0; a < 3; ++a) h[1 + a] = float(g[i][a]);
        }
    }
};

// Marches the listed rays of a band to their hits (or misses), writing hits[4·pixel ...].
// `progress(done)`: the fraction of the listed rays that finished, after each step.
void march_rays(const PointEvaluator& field, Rays& rays, std::vector<std::size_t> listed, const March& m,
                std::vector<float>& hits, std::string& device, const std::function<void(double)>& progress) {
    const double count = double(std::max<std::size_t>(listed.size(), 1));
    BandMarch band{field, rays, m, device, std::move(listed), {}, {}};
    band.start();
    for (int s = 0; s < m.max_steps && !band.marching.empty(); ++s) {
        band.step();
        if (progress) progress(1.0 - double(band.marching.size()) / count);
    }
    band.bisect();
    band.write_hits(hits);
}

}  // namespace

std::vector<float> march_wavefront(const PointEvaluator& field, const Camera& cam, const March& m, std::string& device,
                                   const ProgressFn& progress) {
    const long n = long(cam.width) * cam.height;
    std::vector<float> hits(std::size_t(4 * n), 0.0f);
    for (long p = 0; p < n; ++p) hits[std::size_t(4 * p)] = -1;
    device = "cpu";
    // Bands of rays bound the memory (a ray's state and its points: ~200 bytes) and report
    // progress. Each band ends in a tail of steps over a few long rays, a dispatch each on a
    // device: 2^19 rays (100 MB) take a 640×480 picture, or 320×240 at 2×2 rays a pixel, in one.
    constexpr long kBand = 1L << 19;
    for (long first = 0; first < n; first += kBand) {
        const long last = std::min(n, first + kBand);
        // The band's rays that enter the box and, past its empty cells, are still in it: set up
        // by the whole team, whatever the field's evaluations share (no evaluation runs yet).
        // A 320×240 picture at 2×2 rays a pixel skips ~3·10⁵ rays through up to a few dozen
        // cells each here: one thread took 77–125 ms of the 0.7 s it took lavapipe to render a
        // 2048-point PAT field, two 47–88 (five runs each).
        Rays rays(std::size_t(last - first));
#pragma omp parallel for schedule(static)
        for (long p = first; p < last; ++p) {
            Ray& r = rays[std::size_t(p - first)];
            r.d = cam.ray(int(p % cam.width), int(p / cam.width));
            r.pixel = -1;
            double t0, t1;
            if (!clip_to_box(m.box, cam.eye, r.d, t0, t1)) continue;
            r.o = cam.eye + t0 * r.d;  // from the box entry, as march_ray
            r.entry = t0;
            r.span = t1 - t0;
            if (skip_empty(m, r.o, r.d, r.span, r.t, 0)) r.pixel = p;
        }
        rays.erase(std::remove_if(rays.begin(), rays.end(), [](const Ray& r) { return r.pixel < 0; }), rays.end());
        auto report = [&](double done) {
            if (progress) progress("march", (double(first) + double(last - first) * done) / double(n));
        };
        // From here on the field's evaluations alternate with the host's steps.
        const detail::OneOpenMPThread serial(field.shares_cores);
        std::vector<std::size_t> all(rays.size());
        for (std::size_t k = 0; k < rays.size(); ++k) all[k] = k;
        march_rays(field, rays, std::move(all), m, hits, device, report);
        report(1.0);
    }
    return hits;
}

}  // namespace gsd::render
