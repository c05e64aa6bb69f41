// gsd/viz.hpp — turning scalar grids into things people look at: iso-surfaces and slices.
#pragma once

#include <gsd/core.hpp>

#include <string>
#include <vector>

namespace gsd {

/// Extracts the level set {φ = iso} of a grid (values in GridSpec storage order) as a triangle
/// mesh by marching cubes, with vertices shared between neighboring cells. Triangles are
/// oriented so their normals point toward increasing φ (outward for a signed distance), and
/// where the level set is closed inside the grid the mesh is closed, manifold and
/// consistently oriented. Non-finite values are rejected.
PolygonMesh contour(const GridSpec& grid, const std::vector<float>& values, double iso = 0.0);

/// Which axis a slice is perpendicular to.
enum class Axis { X = 0, Y = 1, Z = 2 };

struct SliceOptions {
    Axis axis = Axis::Z;
    double at = 0.0;          ///< world coordinate of the slice plane (trilinear in between nodes)
    int width = 0;            ///< output pixels along the slice's first axis (0: 512, or the grid size if larger)
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
Image render_slice(const GridSpec& grid, const std::vector<float>& values, const SliceOptions& opt);

/// Writes an image as PNG (atomically).
void write_png(const std::string& path, const Image& image);

}  // namespace gsd
