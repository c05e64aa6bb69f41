// The field renderer: camera, the CPU reference march (double precision), shading, and the
// choice between it and the shaders (render_gpu.cpp).
#include "render/render.hpp"
#include "core/grid_sampling.hpp"

#include <gsd/baselines.hpp>
#include <gsd/field_algebra.hpp>
#include "gpu/on_device.hpp"
#include <gsd/pat.hpp>

#include "blend/blend.hpp"
#include "gpu/field_device.hpp"
#include "viz/palette.hpp"

#include <algorithm>
#include <cmath>

namespace gsd::render {

Eigen::Vector3d Camera::ray(int px, int py) const { return view().ray(px, py, width, height); }

Camera make_camera(const Box& box, const FieldRenderOptions& o, int width, int height) {
    Camera c;
    c.width = width;
    c.height = height;
    const Eigen::Vector3d center = 0.5 * (box.lo + box.hi);
    const double radius = 0.5 * box.diagonal();
    const double half = 0.5 * o.fov_degrees * M_PI / 180.0;
    const double aspect = double(width) / height;
    // The sphere must fit the narrower of the two fields of view.
    const double half_narrow = aspect >= 1 ? half : std::atan(std::tan(half) * aspect);
    const Eigen::Vector3d from = o.eye ? Eigen::Vector3d((*o.eye - center).normalized()) : o.view_from.normalized();
    c.eye = o.eye ? *o.eye : Eigen::Vector3d(center + from * (radius / std::sin(half_narrow)));
    c.forward = -from;
    const Eigen::Vector3d right = c.forward.cross(o.up).normalized();
    const Eigen::Vector3d up = right.cross(c.forward);
    c.up = up * std::tan(half);
    c.right = right * std::tan(half) * aspect;
    return c;
}

March make_march(const Box& box, const FieldRenderOptions& o) {
    March m;
    m.box = box;
    m.max_steps = o.max_steps;
    m.step_scale = o.step_scale;
    m.hit_eps = o.hit_tolerance > 0 ? o.hit_tolerance : 1e-4 * box.diagonal();
    m.min_step = m.hit_eps;
    m.bisection = o.bisection_steps;
    m.chunk = o.chunk_size;
    return m;
}

bool clip_to_box(const Box& b, const Eigen::Vector3d& o, const Eigen::Vector3d& d, double& t0, double& t1) {
    t0 = 0;
    t1 = 3e38;
    for (int a = 0; a < 3; ++a) {
        if (std::abs(d[a]) < 1e-30) {
            if (o[a] < b.lo[a] || o[a] > b.hi[a]) return false;
            continue;
        }
        const double ta = (b.lo[a] - o[a]) / d[a], tb = (b.hi[a] - o[a]) / d[a];
        t0 = std::max(t0, std::min(ta, tb));
        t1 = std::min(t1, std::max(ta, tb));
    }
    return t0 <= t1;
}

Eigen::Vector4d march_ray(const Sampler& field, const Eigen::Vector3d& eye, const Eigen::Vector3d& d, const March& m) {
    const Eigen::Vector4d miss(-1, 0, 0, 0);
    double t0, t1;
    if (!clip_to_box(m.box, eye, d, t0, t1)) return miss;
    // From the box entry, as the shader does (it keeps float32 steps exact for far cameras).
    const Eigen::Vector3d o = eye + t0 * d;
    const double span = t1 - t0;
    double t = 0, hit = -1;
    if (!skip_empty(m, o, d, span, t, 0)) return miss;
    double phi = field(o + t * d, nullptr);
    if (std::abs(phi) < m.hit_eps) hit = t;
    for (int s = 0; hit < 0 && s < m.max_steps; ++s) {
        double tn = t + std::max(m.step_scale * std::abs(phi), m.min_step);
        const double stepped = tn;
        if (tn > span || !skip_empty(m, o, d, span, tn, phi < 0 ? -1 : 1)) break;
        const double pn = field(o + tn * d, nullptr);
        if (tn != stepped) {
            // Skipped through empty cells, which hold no surface: a fresh start at tn.
            if (std::abs(pn) < m.hit_eps) hit = tn;
        } else if ((pn < 0) != (phi < 0)) {  // crossed the surface within the step: bisect [t, tn]
            double a = t, b = tn, pa = phi;
            for (int k = 0; k < m.bisection; ++k) {
                const double mid = 0.5 * (a + b), pm = field(o + mid * d, nullptr);
                if ((pm < 0) == (pa < 0)) { a = mid; pa = pm; } else { b = mid; }
            }
            hit = 0.5 * (a + b);
        } else if (std::abs(pn) < m.hit_eps) {
            hit = tn;
        }
        t = tn;
        phi = pn;
    }
    if (hit < 0) return miss;
    Eigen::Vector3d g;
    field(o + hit * d, &g);
    return {t0 + hit, g.x(), g.y(), g.z()};
}

namespace {

void check_options(const FieldRenderOptions& o) {
    auto bad = [](const char* field, const std::string& why) { throw Error(field, why); };
    if (o.width < 1 || o.height < 1 || o.width > 16384 || o.height > 16384)
        bad("FieldRenderOptions::width", "the image size must be 1 to 16384 pixels per side");
    if (o.supersample < 1 || o.supersample > 4) bad("FieldRenderOptions::supersample", "must be 1 to 4");
    if (double(o.width) * o.height * o.supersample * o.supersample > 1e8)
        bad("FieldRenderOptions::width", "width × height × supersample² must stay within 10^8 rays");
    if (!o.view_from.allFinite() || o.view_from.norm() < 1e-12) bad("FieldRenderOptions::view_from", "must be a finite, non-zero direction");
    if (o.eye && !o.eye->allFinite()) bad("FieldRenderOptions::eye", "must be finite");
    if (!o.up.allFinite() || o.view_from.normalized().cross(o.up).norm() < 1e-9 * std::max(o.up.norm(), 1e-300))
        bad("FieldRenderOptions::up", "must be finite and not parallel to view_from");
    if (!(o.fov_degrees > 1 && o.fov_degrees < 170)) bad("FieldRenderOptions::fov_degrees", "must be between 1 and 170");
    if (o.max_steps < 1 || o.max_steps > 100000) bad("FieldRenderOptions::max_steps", "must be 1 to 100000");
    if (!(o.step_scale > 0 && o.step_scale <= 1)) bad("FieldRenderOptions::step_scale", "must be in (0, 1]");
    if (!(o.hit_tolerance >= 0) || !std::isfinite(o.hit_tolerance)) bad("FieldRenderOptions::hit_tolerance", "must be finite and ≥ 0");
    if (o.bisection_steps < 0 || o.bisection_steps > 64) bad("FieldRenderOptions::bisection_steps", "must be 0 to 64");
    if (!(o.color_range >= 0) || !std::isfinite(o.color_range)) bad("FieldRenderOptions::color_range", "must be finite and ≥ 0");
    if (bool(o.color_grid) != bool(o.color_values))
        bad("FieldRenderOptions::color_grid", "a color field needs both color_grid and color_values");
    if (o.color_grid) {
        o.color_grid->validate();
        if (o.color_values->size() != o.color_grid->node_count())
            bad("FieldRenderOptions::color_values", "has " + std::to_string(o.color_values->size()) +
                                                         " values for a grid of " + std::to_string(o.color_grid->node_count()) + " nodes");
    }
}

// Turns per-pixel hits into a picture: Lambert + ambient light from the camera's side, colored
// uniformly or by the color field, then box-downsampled.
RenderedField shade(const std::vector<float>& hits, const Camera& cam, const FieldRenderOptions& o, std::string device) {
    RenderedField r;
    r.render_width = cam.width;
    r.render_height = cam.height;
    r.device = std::move(device);
    r.camera = cam.view();
    const std::size_t n = std::size_t(cam.width) * std::size_t(cam.height);
    r.depth.resize(n);
    const Eigen::Vector3d light = (-cam.forward + 0.5 * cam.up.normalized() - 0.35 * cam.right.normalized()).normalized();

    std::vector<double> color_value(n, std::nan(""));
    double range = o.color_range;
    std::size_t hit_count = 0;
    for (std::size_t p = 0; p < n; ++p) {
        r.depth[p] = hits[4 * p] >= 0 ? hits[4 * p] : -1.0f;
        if (hits[4 * p] < 0) continue;
        ++hit_count;
        if (o.color_grid) {
            const Eigen::Vector3d x = cam.eye + double(hits[4 * p]) * cam.ray(int(p % std::size_t(cam.width)), int(p / std::size_t(cam.width)));
            color_value[p] = detail::trilinear(*o.color_grid, *o.color_values, x, nullptr);
            if (o.color_range == 0 && std::isfinite(color_value[p])) range = std::max(range, std::abs(color_value[p]));
        }
    }
    r.hit_fraction = n ? double(hit_count) / double(n) : 0;
    if (range <= 0) range = 1;

    std::vector<double> rgb(3 * n);
    for (std::size_t p = 0; p < n; ++p) {
        viz::Rgb c{double(o.background[0]), double(o.background[1]), double(o.background[2])};
        if (hits[4 * p] >= 0) {
            const Eigen::Vector3d d = cam.ray(int(p % std::size_t(cam.width)), int(p / std::size_t(cam.width)));
            Eigen::Vector3d normal(hits[4 * p + 1], hits[4 * p + 2], hits[4 * p + 3]);
            normal = normal.norm() > 0 ? normal.normalized() : Eigen::Vector3d(-d);
            if (normal.dot(d) > 0) normal = -normal;  // seen from inside: light the side we see
            const double lambert = 0.25 + 0.75 * std::max(0.0, normal.dot(light));
            viz::Rgb base{double(o.color[0]), double(o.color[1]), double(o.color[2])};
            if (o.color_grid) base = std::isfinite(color_value[p]) ? viz::diverging(color_value[p] / range) : viz::kNoValue;
            c = {base.r * lambert, base.g * lambert, base.b * lambert};
        }
        rgb[3 * p] = c.r;
        rgb[3 * p + 1] = c.g;
        rgb[3 * p + 2] = c.b;
    }
    const int ss = o.supersample;
    r.image.width = cam.width / ss;
    r.image.height = cam.height / ss;
    r.image.rgb.resize(std::size_t(r.image.width) * std::size_t(r.image.height) * 3);
    for (int y = 0; y < r.image.height; ++y)
        for (int x = 0; x < r.image.width; ++x)
            for (int ch = 0; ch < 3; ++ch) {
                double sum = 0;
                for (int dy = 0; dy < ss; ++dy)
                    for (int dx = 0; dx < ss; ++dx)
                        sum += rgb[3 * (std::size_t(y * ss + dy) * std::size_t(cam.width) + std::size_t(x * ss + dx)) + std::size_t(ch)];
                r.image.rgb[3 * (std::size_t(y) * std::size_t(r.image.width) + std::size_t(x)) + std::size_t(ch)] =
                    viz::to_byte(sum / (ss * ss));
            }
    return r;
}

// Marches every pixel on the CPU, each thread with its own sampler (scratch space), in bands
// of rows so progress can be reported between them.
std::vector<float> march_cpu(const std::function<Sampler()>& make_sampler, const Camera& cam, const March& m,
                             const ProgressFn& progress) {
    const long n = long(cam.width) * cam.height;
    const long band = std::max<long>(1, (1L << 16) / cam.width) * cam.width;
    std::vector<float> hits(std::size_t(4 * n));
    for (long first = 0; first < n; first += band) {
        const long last = std::min(n, first + band);
#pragma omp parallel
        {
            const Sampler field = make_sampler();
#pragma omp for schedule(dynamic, 64)
            for (long p = first; p < last; ++p) {
                const Eigen::Vector4d h = march_ray(field, cam.eye, cam.ray(int(p % cam.width), int(p / cam.width)), m);
                for (int c = 0; c < 4; ++c) hits[std::size_t(4 * p + c)] = float(h[c]);
            }
        }
        if (progress) progress("march", double(last) / double(n));
    }
    return hits;
}

struct Frame {
    Camera cam;
    March march;
};

// `subject`: where the surface can be (the cloud's box, a grid's nodes near or below zero),
// which the camera frames; the rays march in all of `box`.
Frame frame_for(const Box& box, Box subject, const FieldRenderOptions& o) {
    check_options(o);
    validate_box(box, "box");
    subject.lo = subject.lo.cwiseMax(box.lo);
    subject.hi = subject.hi.cwiseMin(box.hi);
    if (!((subject.hi - subject.lo).array() > 0).all()) subject = box;
    if (o.eye) {  // the explicit eye must see the center along a direction not parallel to up
        const Eigen::Vector3d d = 0.5 * (subject.lo + subject.hi) - *o.eye;
        if (d.norm() < 1e-12 * box.diagonal() || d.normalized().cross(o.up).norm() < 1e-9 * o.up.norm())
            throw Error("FieldRenderOptions::eye", "must be away from the center of the surface's box, and not straight above or below it (along up)");
    }
    Frame f;
    f.cam = make_camera(subject, o, o.width * o.supersample, o.height * o.supersample);
    f.march = make_march(box, o);
    return f;
}

// The box of the nodes within half a cell diagonal of φ ≤ 0: where a grid's surface can be.
Box grid_subject(const GridSpec& g, const std::vector<float>& values) {
    const double reach = 0.5 * g.box.extent().cwiseQuotient(Eigen::Vector3d(g.nx - 1, g.ny - 1, g.nz - 1)).norm();
    Box b{Eigen::Vector3d::Constant(1e300), Eigen::Vector3d::Constant(-1e300)};
    for (int i = 0; i < g.nx; ++i)
        for (int j = 0; j < g.ny; ++j)
            for (int k = 0; k < g.nz; ++k)
                if (values[(std::size_t(i) * std::size_t(g.ny) + std::size_t(j)) * std::size_t(g.nz) + std::size_t(k)] <= reach) {
                    const Eigen::Vector3d x = g.node(i, j, k);
                    b.lo = b.lo.cwiseMin(x);
                    b.hi = b.hi.cwiseMax(x);
                }
    return b;
}

// Rays the device left unfinished (t = −2: llvmpipe's loop limit, render_march.glsl) marched on
// the CPU, with one line saying so.
void redo_unfinished(std::vector<float>& hits, const std::function<Sampler()>& make_sampler, const Camera& cam,
                     const March& m, const std::string& device) {
    std::vector<long> redo;
    for (std::size_t p = 0; 4 * p < hits.size(); ++p)
        if (hits[4 * p] == -2.0f) redo.push_back(long(p));
    if (redo.empty()) return;
    log_once(std::to_string(redo.size()) + " rays past " + device + "'s loop limit were marched on the CPU");
#pragma omp parallel
    {
        const Sampler field = make_sampler();
#pragma omp for schedule(dynamic, 16)
        for (std::size_t i = 0; i < redo.size(); ++i) {
            const long p = redo[i];
            const Eigen::Vector4d h = march_ray(field, cam.eye, cam.ray(int(p % cam.width), int(p / cam.width)), m);
            for (int c = 0; c < 4; ++c) hits[std::size_t(4 * p + c)] = float(h[c]);
        }
    }
}

// The march on the chosen device, else (no device, or the field does not fit it) on the CPU,
// then the shading both share. `march_on(ctx, hits, why_not)` marches on a context and says why
// it could not (a generic lambda: gpu::on_device); it may set f.march.empty, which the CPU then
// uses for the rays the device left. `before_cpu`, if set, readies f.march for the CPU's march.
template <class DeviceMarch>
RenderedField march_and_shade(Frame& f, const FieldRenderOptions& o, const DeviceMarch& march_on,
                              const std::function<Sampler()>& make_sampler, const ProgressFn& progress,
                              const std::function<void()>& before_cpu = {}) {
    std::vector<float> hits;
    const gpu::DeviceRun run = gpu::on_device(
        o.device, [&](const auto& ctx, std::string& why_not) { return march_on(ctx, hits, why_not); },
        "; rendering on the CPU");
    RenderedField r;
    if (run) {
        redo_unfinished(hits, make_sampler, f.cam, f.march, run.device);
        r = shade(hits, f.cam, o, run.device);
    } else {
        if (before_cpu) before_cpu();
        hits = march_cpu(make_sampler, f.cam, f.march, progress);
        r = shade(hits, f.cam, o, "cpu");
    }
    r.empty_cells = f.march.empty ? f.march.empty->empty_cells : 0;
    return r;
}

RenderedField render_blend(const blend::Engine& engine, const Box& box, const FieldRenderOptions& o,
                           const ProgressFn& progress) {
    Frame f = frame_for(box, bounding_box(engine.source().points), o);
    blend::Params params = engine.params(true);
    params.exact = false;  // the shader marches the accelerated sum; so does its reference
    const blend::Source& src = engine.source();
    const spatial::BoxTree& tree = engine.search_tree();
    const int cells = o.skip_empty_space ? empty_space_resolution(f.cam) : 0;
    return march_and_shade(
        f, o,
        [&](const auto& ctx, std::vector<float>& hits, std::string& why_not) {
            return march_blend_gpu(engine, ctx, f.cam, f.march, cells, hits, why_not, progress);
        },
        [&] {
            auto scratch = std::make_shared<std::vector<Neighbor>>();
            return Sampler([&src, &tree, params, scratch](const Eigen::Vector3d& x, Eigen::Vector3d* g) {
                return blend::evaluate_one(src, tree, params, x, g, *scratch);
            });
        },
        progress,
        [&] {
            if (!cells) return;
            blend::Params p = params;
            p.gradient = false;
            f.march.empty = std::make_shared<EmptySpace>(find_empty_space(f.march.box, cells, f.march.step_scale, [&](const GridSpec& g) {
                std::vector<float> phi(g.node_count());
                blend::evaluate_cpu(src, tree, p, blend::Queries(g), blend::Output{phi.data(), nullptr}, {});
                return phi;
            }));
        });
}

}  // namespace
}  // namespace gsd::render

namespace gsd {

RenderedField render_field(const GridSpec& grid, const std::vector<float>& values, const FieldRenderOptions& options,
                           const ProgressFn& progress) {
    grid.validate();
    if (grid.nx < 2 || grid.ny < 2 || grid.nz < 2) throw Error("grid", "needs at least 2 nodes along each axis");
    if (values.size() != grid.node_count())
        throw Error("values", "has " + std::to_string(values.size()) + " values for a grid of " +
                                  std::to_string(grid.node_count()) + " nodes");
    for (float v : values)
        if (!std::isfinite(v)) throw Error("values", "contain NaN or infinite values");
    render::Frame f = render::frame_for(grid.box, render::grid_subject(grid, values), options);
    return render::march_and_shade(
        f, options,
        [&](const auto& ctx, std::vector<float>& hits, std::string& why_not) {
            return render::march_grid_gpu(grid, values, ctx, f.cam, f.march, hits, why_not, progress);
        },
        [&] {
            return render::Sampler([&](const Eigen::Vector3d& x, Eigen::Vector3d* g) {
                return detail::trilinear(grid, values, x, g);
            });
        },
        progress);
}

RenderedField render_field(const Field& field, const Box& box, const FieldRenderOptions& options,
                           const ProgressFn& progress) {
    // The fields with a march of their own: a blend (render_pat on a device, the CPU reference
    // per ray), a grid (render_grid).
    if (const auto* p = dynamic_cast<const blend::EngineProgram*>(field.device_program()))
        return render::render_blend(p->engine(), box, options, progress);
    if (const auto* f = dynamic_cast<const GridField*>(&field)) return render_field(f->grid(), f->values(), options, progress);
    // Where the surface can be, for the camera's framing: the nodes of a coarse grid over the box
    // within half a cell of φ ≤ 0 (a few thousand evaluations, against the march's millions).
    validate_box(box, "box");
    const GridSpec coarse{24, 24, 24, box};
    render::Frame f = render::frame_for(box, render::grid_subject(coarse, field.evaluate(coarse).phi), options);
    // Any other field: the wavefront march, its evaluations by the field's device program where
    // it has one and a device is chosen, else by its evaluate() on the CPU.
    render::PointEvaluator eval{[&](const Points& x, bool gradient) { return field.evaluate(x, gradient); },
                                field.has_gradient()};
    gpu::on_device(
        options.device,
        [&](const auto& ctx, std::string& why_not) {
            if (!field.device_program()) {
                why_not = "the field has no device program (nor has any of its leaves)";
                return false;
            }
            eval.evaluate = [&field, ctx](const Points& x, bool gradient) { return gpu::evaluate_points(field, ctx, x, gradient); };
            // As for a blend (render_gpu.cpp), a software device's evaluations share the host's
            // cores: a smooth union of two PAT fields of 2048 points at 320×240 on lavapipe
            // 1.52–1.56 → 1.32–1.37 s, three runs in turn, the same picture. (No evaluate_few:
            // the field's own evaluate() runs its leaves wherever their options say, a device
            // again by default.)
            eval.shares_cores = gpu::shares_host_cores(*ctx);
            return true;
        },
        "; its rays are marched on the CPU");
    if (options.skip_empty_space) {
        const int cells = render::empty_space_resolution(f.cam);
        f.march.empty = std::make_shared<render::EmptySpace>(render::find_empty_space(
            f.march.box, cells, f.march.step_scale, [&](const GridSpec& g) { return eval.evaluate(g.nodes(), false).phi; }));
    }
    std::string device;
    const std::vector<float> hits = render::march_wavefront(eval, f.cam, f.march, device, progress);
    RenderedField r = render::shade(hits, f.cam, options, device);
    r.empty_cells = f.march.empty ? f.march.empty->empty_cells : 0;
    return r;
}

}  // namespace gsd
