// The field renderer's internals (gsd/render.hpp): the camera, the march shared by the CPU
// reference and the shaders (shaders/render_march.glsl), and the device paths.
#pragma once

#include <gsd/render.hpp>

#include <Eigen/Core>
#include <Eigen/Geometry>  // cross products

#include <functional>
#include <memory>
#include <string>
#include <vector>

namespace gsd {
namespace blend {
class Engine;
}
namespace gpu {
class Context;
}

namespace render {

/// A pinhole camera: the ray of pixel (x, y) is forward + u·right + v·up, u and v in [−1, 1].
struct Camera {
    Eigen::Vector3d eye, forward, right, up;  // right and up scaled by the half field of view
    int width = 0, height = 0;
    Eigen::Vector3d ray(int px, int py) const;
    RenderCamera view() const { return {eye, forward, right, up}; }
};

/// How rays march (FieldRenderOptions resolved for a box).
struct March {
    Box box;
    int max_steps = 256;
    double step_scale = 0.9, hit_eps = 0, min_step = 0;
    int bisection = 12;
    std::size_t chunk = 0;  ///< rays per GPU submission (FieldRenderOptions::chunk_size; 0: the device's default)
};

/// A camera looking at `subject` (where the surface is) from FieldRenderOptions::view_from,
/// framing the subject's bounding sphere.
Camera make_camera(const Box& subject, const FieldRenderOptions& o, int width, int height);
March make_march(const Box& box, const FieldRenderOptions& o);

/// The part [t0, t1] of the ray o + t·d (t ≥ 0) inside the box; false when it misses.
bool clip_to_box(const Box& b, const Eigen::Vector3d& o, const Eigen::Vector3d& d, double& t0, double& t1);

/// φ at x, and ∇φ into `grad` when it is not null.
using Sampler = std::function<double(const Eigen::Vector3d& x, Eigen::Vector3d* grad)>;

/// The march of one ray (the CPU reference of render_march.glsl): (t, ∇φ at the hit), t = −1
/// for a miss.
Eigen::Vector4d march_ray(const Sampler& field, const Eigen::Vector3d& o, const Eigen::Vector3d& d, const March& m);

/// How the wavefront march evaluates its field: φ (and ∇φ) at many points in one call — the
/// field's CPU evaluate(), or its device program through gpu::evaluate_into.
struct PointEvaluator {
    std::function<FieldValues(const Points&, bool gradient)> evaluate;
    bool has_gradient = false;
};

/// Per-pixel hits, 4 floats each (t, ∇φ; t = −1 for a miss), of any field marched on the CPU a
/// band of rays at a time, one evaluation of the field per step (wavefront.cpp). `device`: where
/// the field's evaluations ran.
std::vector<float> march_wavefront(const PointEvaluator& field, const Camera& cam, const March& m, std::string& device,
                                   const ProgressFn& progress);

/// Per-pixel hits, 4 floats each (t, ∇φ), from a device; false (and why) when it cannot run
/// there, so the caller marches on the CPU instead.
bool march_blend_gpu(const blend::Engine& engine, const std::shared_ptr<gpu::Context>& ctx, const Camera& cam,
                     const March& m, std::vector<float>& hits, std::string& why_not, const ProgressFn& progress);
bool march_grid_gpu(const GridSpec& grid, const std::vector<float>& values, const std::shared_ptr<gpu::Context>& ctx,
                    const Camera& cam, const March& m, std::vector<float>& hits, std::string& why_not,
                    const ProgressFn& progress);

}  // namespace render
}  // namespace gsd
