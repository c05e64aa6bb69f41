// The field renderer's internals (gsd/render.hpp): the camera, the march shared by the CPU
// reference and the shaders (shaders/render_march.glsl), and the device paths.
#pragma once

#include <gsd/render.hpp>

#include <Eigen/Core>
#include <Eigen/Geometry>  // cross products

#include <cstdint>
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

/// Where the march may skip ahead without evaluating the field (empty_space.cpp): a coarse grid
/// of cubic cells over the march's box, a cell empty when φ has one sign at its 8 corners and
/// every point of it lies within step_scale·|φ| of a corner — the step a march from that corner
/// would take, so the skip trusts |φ| as a distance exactly as far as the march itself does. A
/// ray in an empty cell goes on past the empty cells ahead of it without evaluating φ.
struct EmptySpace {
    Eigen::Vector3d lo = Eigen::Vector3d::Zero();
    double h = 0;                     ///< the cells' side
    int n[3] = {0, 0, 0};             ///< cells along x, y, z
    /// Two bits per cell, C order (x slowest): words [0, W) say which cells are empty, words
    /// [W, 2W) which of those are negative (W = words()).
    std::vector<std::uint32_t> bits;
    std::size_t empty_cells = 0;

    std::size_t words() const { return (cell_count() + 31) / 32; }

    std::size_t cell_count() const { return std::size_t(n[0]) * std::size_t(n[1]) * std::size_t(n[2]); }
    /// The grid of the cells' corners, where φ is sampled.
    GridSpec corners() const;
    std::size_t cell(const int c[3]) const {
        return (std::size_t(c[0]) * std::size_t(n[1]) + std::size_t(c[1])) * std::size_t(n[2]) + std::size_t(c[2]);
    }
    bool is_empty(std::size_t cell) const { return (bits[cell >> 5] >> (cell & 31)) & 1u; }
    bool is_negative(std::size_t cell) const { return (bits[words() + (cell >> 5)] >> (cell & 31)) & 1u; }
    /// Where the ray o + t·d goes on to without evaluating φ: past the run of empty cells it is
    /// in (a hair past the last one's exit), or t itself when its cell is not empty. `sign`: the
    /// sign of φ where the ray last sampled it (+1 or −1; 0 before its first sample); a cell of
    /// the other sign is not skipped, so that the sample there sees the crossing on the way in.
    /// (Face-adjacent empty cells share 4 corners, so a run of them has one sign.)
    double skip(const Eigen::Vector3d& o, const Eigen::Vector3d& d, double t, int sign) const;
};

/// φ at the nodes of a grid (C order), float: how an EmptySpace is sampled on either path.
using NodeSampler = std::function<std::vector<float>(const GridSpec&)>;

/// Cells along the box's longest side for the camera's picture: about one corner sample for
/// every 8 of its rays (8 to 64), a few percent of the march's evaluations.
int empty_space_resolution(const Camera& cam);

/// The empty cells of a field over `box`, `cells` along its longest side.
EmptySpace find_empty_space(const Box& box, int cells, double step_scale, const NodeSampler& phi_at_nodes);

/// How rays march (FieldRenderOptions resolved for a box).
struct March {
    Box box;
    int max_steps = 256;
    double step_scale = 0.9, hit_eps = 0, min_step = 0;
    int bisection = 12;
    std::size_t chunk = 0;  ///< rays per GPU submission (FieldRenderOptions::chunk_size; 0: the device's default)
    std::shared_ptr<const EmptySpace> empty;  ///< where it may skip ahead; null: nowhere
};

/// A camera looking at `subject` (where the surface is) from FieldRenderOptions::view_from,
/// framing the subject's bounding sphere.
Camera make_camera(const Box& subject, const FieldRenderOptions& o, int width, int height);
March make_march(const Box& box, const FieldRenderOptions& o);

/// Moves t on through empty cells (m.empty) while the ray o + t·d is in one of sign `sign`
/// (EmptySpace::skip); false when that takes it past `span` (a miss).
bool skip_empty(const March& m, const Eigen::Vector3d& o, const Eigen::Vector3d& d, double span, double& t, int sign);

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
    /// Its evaluations run on the host's own cores (a software device's threads): between
    /// them the march's steps keep to one OpenMP thread (detail::OneOpenMPThread says why); only
    /// the rays' set-up, before any evaluation, takes the whole team.
    bool shares_cores = false;
    /// Optional: the same field evaluated on the host, for calls of at most kFewPoints points —
    /// a band's last rays, where a round trip to the device costs more than their sums.
    std::function<FieldValues(const Points&, bool gradient)> evaluate_few;
    static constexpr std::size_t kFewPoints = 128;

    /// The evaluator for a call of `points` points: evaluate_few where it applies.
    const std::function<FieldValues(const Points&, bool gradient)>& for_points(std::size_t points) const {
        return evaluate_few && points <= kFewPoints ? evaluate_few : evaluate;
    }
};

/// Per-pixel hits, 4 floats each (t, ∇φ; t = −1 for a miss), of any field marched on the CPU a
/// band of rays at a time, one evaluation of the field per step (wavefront.cpp). `device`: where
/// the field's evaluations ran.
std::vector<float> march_wavefront(const PointEvaluator& field, const Camera& cam, const March& m, std::string& device,
                                   const ProgressFn& progress);

/// Per-pixel hits, 4 floats each (t, ∇φ), from a device; false (and why) when it cannot run
/// there, so the caller marches on the CPU instead.
/// march_blend_gpu first finds the empty space (`empty_cells` along the box's longest side; 0:
/// none) with the device and puts it in m.empty.
bool march_blend_gpu(const blend::Engine& engine, const std::shared_ptr<gpu::Context>& ctx, const Camera& cam,
                     March& m, int empty_cells, std::vector<float>& hits, std::string& why_not, const ProgressFn& progress);
bool march_grid_gpu(const GridSpec& grid, const std::vector<float>& values, const std::shared_ptr<gpu::Context>& ctx,
                    const Camera& cam, const March& m, std::vector<float>& hits, std::string& why_not,
                    const ProgressFn& progress);

}  // namespace render
}  // namespace gsd
