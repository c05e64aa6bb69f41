// gsd/render.hpp — pictures of a field's zero level set, sphere-traced (thesis fig. 5.3).
//
//   gsd::FieldRenderOptions o;                    // 800×600, a three-quarter view
//   gsd::RenderedField r = gsd::render_field(field, box, o);   // any gsd::Field
//   gsd::write_png("surface.png", r.image);
//
// Every pixel's ray is clipped to a box and marched by the field's own value (sphere tracing)
// until |φ| is below a tolerance or φ changes sign (then bisected); the hit is shaded by ∇φ
// (Lambert and ambient light from the camera's side) and colored uniformly or by a second
// field. The marching runs in a compute shader on a Vulkan device, or on the CPU (double
// precision, the reference the tests hold the shader to), by the usual device choice.
#pragma once

#include <gsd/export.hpp>

#include <gsd/core.hpp>
#include <gsd/field.hpp>
#include <gsd/gpu.hpp>
#include <gsd/viz.hpp>

#include <array>
#include <optional>
#include <string>
#include <vector>

namespace gsd {

/// Where it runs and the rays per GPU submission (0: 2^20 on a GPU, 65 536 on a software
/// device): Execution (gsd/gpu.hpp).
struct FieldRenderOptions : Execution {
    int width = 800, height = 600;
    /// Direction the camera looks from, toward the center of the surface's box (need not be
    /// unit); the distance is chosen to frame that box.
    Eigen::Vector3d view_from{1.0, 0.8, 1.6};
    /// Or an explicit camera position, looking at the same center (overrides view_from).
    std::optional<Eigen::Vector3d> eye;
    Eigen::Vector3d up{0, 1, 0};  ///< must not be parallel to view_from
    double fov_degrees = 35;      ///< vertical field of view; the camera frames the whole box
    int max_steps = 256;          ///< march steps per ray before it counts as a miss
    /// Each step advances step_scale·|φ|: below 1 because a blended field is only close to a
    /// distance (it may overestimate it a little away from the surface).
    double step_scale = 0.9;
    /// |φ| below this is a hit (0: 1e-4 of the box diagonal). Also the smallest step.
    double hit_tolerance = 0;
    int bisection_steps = 12;     ///< refinement of a hit found by a sign change
    /// Blended fields (PAT, SSPD, SHC): first sample φ at the corners of a coarse grid (about
    /// one sample for 8 rays) and let rays cross the cells that hold no surface without
    /// evaluating φ there (docs/render.md, "Empty space").
    bool skip_empty_space = true;
    int supersample = 1;          ///< render at this factor and box-downsample (antialiasing), 1 to 4
    std::array<std::uint8_t, 3> color{200, 200, 205};      ///< surface color without a color field
    std::array<std::uint8_t, 3> background{255, 255, 255};
    /// Optional second field coloring the surface (diverging map of render_slice, ±color_range;
    /// 0: max |value| at the hits): a grid of values, sampled trilinearly at each hit.
    const GridSpec* color_grid = nullptr;
    const std::vector<float>* color_values = nullptr;
    double color_range = 0;
};

/// The camera a picture was taken with. The ray through pixel (x, y) of a W×H render (the
/// supersampled one) leaves `eye` along forward + u·right + v·up, normalized, with
/// u = 2(x + ½)/W − 1 and v = 1 − 2(y + ½)/H.
struct RenderCamera {
    Eigen::Vector3d eye, forward, right, up;
    Eigen::Vector3d ray(int x, int y, int width, int height) const {
        const double u = 2.0 * (x + 0.5) / width - 1.0, v = 1.0 - 2.0 * (y + 0.5) / height;
        return (forward + u * right + v * up).normalized();
    }
};

/// A rendered picture and what it took.
struct RenderedField {
    Image image;
    /// Per pixel of the (supersampled) render, top row first: the ray parameter of the hit,
    /// distance from the eye along the unit ray; −1 where the ray missed.
    std::vector<float> depth;
    int render_width = 0, render_height = 0;  ///< the supersampled size `depth` has
    double hit_fraction = 0;                  ///< share of rays that hit the surface
    std::string device;                       ///< "cpu" or the Vulkan device that marched
    /// Cells of the coarse grid the rays crossed without evaluating φ
    /// (FieldRenderOptions::skip_empty_space; 0 when off, or for a grid).
    std::size_t empty_cells = 0;
    RenderCamera camera;
};

/// Renders any field's zero set inside `box`. A PAT or baseline field is sphere-traced by its
/// own kernel (render_pat: every ray marched on the device, or the CPU reference per ray; the
/// accelerated sum, whatever BlendOptions::exact says); a GridField as its grid below; any other
/// (a composite of gsd/field_algebra.hpp, a MeshSdfField, …) by the wavefront march, every ray
/// of a band together, one evaluation of the field a step, the same march as the CPU
/// reference's: on the chosen device through the field's device program where it has one (a
/// composite has one when any of its leaves has: gpu::evaluate_into), else on the CPU. ∇φ for the
/// shading: the field's, or central differences where it has none. Throws gsd::Error for bad
/// options or an empty box. `progress` hears ("march", fraction done).
GSD_EXPORT RenderedField render_field(const Field& field, const Box& box, const FieldRenderOptions& options = {},
                                      const ProgressFn& progress = {});
/// Renders the zero set of a grid of φ (trilinear between nodes) inside its box.
GSD_EXPORT RenderedField render_field(const GridSpec& grid, const std::vector<float>& values,
                                      const FieldRenderOptions& options = {}, const ProgressFn& progress = {});

}  // namespace gsd
