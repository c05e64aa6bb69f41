// gsd/viz.hpp — turning scalar fields into things people look at: iso-surfaces and slices of
// grids, and pictures of fields on meshes.
#pragma once

#include <gsd/export.hpp>

#include <gsd/core.hpp>

#include <array>
#include <cstdint>
#include <string>
#include <vector>

namespace gsd {

/// Extracts the level set {φ = iso} of a grid (values in GridSpec storage order) as a triangle
/// mesh by marching cubes, with vertices shared between neighboring cells. Triangles are
/// oriented so their normals point toward increasing φ (outward for a signed distance), and
/// where the level set is closed inside the grid the mesh is closed, manifold and
/// consistently oriented. Non-finite values are rejected.
GSD_EXPORT PolygonMesh contour(const GridSpec& grid, const std::vector<float>& values, double iso = 0.0);

/// Which axis a slice is perpendicular to.
enum class Axis { X = 0, Y = 1, Z = 2 };

struct SliceOptions {
    Axis axis = Axis::Z;
    double at = 0.0;          ///< world coordinate of the slice plane (trilinear in between nodes)
    int width = 0;            ///< output pixels along the slice's first axis (0: 512, or the grid size if larger, at most 4096 per side)
    double range = 0.0;       ///< color scale saturates at ±range (0: max |value| on the slice)
    int isolines = 16;        ///< number of isolines each side of zero over ±range (0: none)
    bool zero_contour = true; ///< draw the zero level as a thick dark line
};

/// An 8-bit RGB image, row-major, top row first.
struct Image {
    int width = 0, height = 0;
    std::vector<std::uint8_t> rgb;
};

/// Renders a planar slice through a grid with a diverging color map (blue negative, white
/// zero, red positive), thin isolines and the zero contour, as in the thesis figures.
/// The slice's image axes are the two remaining world axes in order (for Z: x right, y up).
GSD_EXPORT Image render_slice(const GridSpec& grid, const std::vector<float>& values, const SliceOptions& opt);

/// Writes an image as PNG (atomically).
GSD_EXPORT void write_png(const std::string& path, const Image& image);

// ---- fields on surfaces ------------------------------------------------------------------

/// What to draw on a surface picture.
struct SurfacePicture {
    /// Triangles or polygons (fanned); vertex positions define the geometry. Not owned.
    const PolygonMesh* mesh = nullptr;
    /// Either a value per vertex (colored with the diverging map of render_slice, linear over
    /// each triangle, with isolines and a thick zero contour), or a label per face (flat colors
    /// from label_color), or neither (plain gray). A triangle with a NaN or infinite vertex
    /// value is drawn gray.
    std::vector<double> vertex_values;
    std::vector<int> face_labels;
    /// Curves drawn on top (e.g. the input curve, or the curve decomposition of SWN).
    struct Curves {
        Polylines lines;
        std::array<std::uint8_t, 3> color{20, 20, 20};
        double width = 3.0;  ///< pixels (of the final image)
    };
    std::vector<Curves> curves;
};

struct SurfaceRenderOptions {
    int width = 1024, height = 768;
    /// Direction the camera looks from, toward the mesh center (need not be unit). Default: a
    /// three-quarter view from the front-right-top.
    Eigen::Vector3d view_from{1.0, 0.8, 1.6};
    Eigen::Vector3d up{0, 1, 0};  ///< must not be parallel to view_from
    double range = 0;             ///< vertex values: the color scale saturates at ±range (0: max |value|)
    int isolines = 20;            ///< isolines over [−range, range], spacing 2·range/isolines (0: none)
    bool zero_contour = true;     ///< vertex values: draw φ = 0 as a thick dark line
    int supersample = 2;          ///< render at this factor and box-downsample (antialiasing), 1 to 8
    /// Tint faces seen from their back side (opposite their normal) a little yellow and darker,
    /// so flipped or inconsistent orientation and the inside of holey meshes are visible.
    bool mark_back_faces = true;
    std::array<std::uint8_t, 3> background{255, 255, 255};
};

/// Renders a shaded mesh (two-sided Lambert + ambient, perspective camera framing the whole
/// mesh) colored by the picture's field, with curves on top, depth-tested so that curves on
/// the far side of the mesh are hidden. Deterministic. Throws gsd::Error on a missing or
/// invalid mesh, wrong value or label counts, non-finite curve points, bad options, or a
/// render buffer (width·height·supersample²) above 10^8 pixels.
GSD_EXPORT Image render_surface(const SurfacePicture& picture, const SurfaceRenderOptions& options = {});

/// A point cloud as a mesh of splats for render_surface: point i becomes a flat hexagonal disc
/// of radius radii[i] facing normals[i] (its front side), made of vertices
/// kSplatVertices·i … kSplatVertices·(i+1) − 1, the first at the point itself; repeat a value
/// per point kSplatVertices times to color the discs. Throws gsd::Error for mismatched counts,
/// no points, non-finite positions, zero normals or negative radii.
inline constexpr std::size_t kSplatVertices = 7;
GSD_EXPORT PolygonMesh splat_mesh(const Points& points, const Points& normals, const std::vector<double>& radii);

/// The diverging color of render_slice for value x on a scale ±range (range > 0; NaN: the
/// gray of missing values), exposed so other outputs, e.g. colored meshes, match the pictures.
GSD_EXPORT std::array<std::uint8_t, 3> diverging_color(double x, double range);
/// A categorical color for an integer label: 0 off-white, then +1 blue, −1 orange, +2 green,
/// −2 red, +3 purple, −3 brown, +4 pink, −4 olive, +5 cyan; further labels repeat the
/// cycle darker.
GSD_EXPORT std::array<std::uint8_t, 3> label_color(int label);

}  // namespace gsd
