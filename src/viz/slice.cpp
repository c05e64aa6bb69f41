// Planar slices through a grid, drawn like the thesis figures: a diverging blue–white–red color
// map, thin isolines and a thick zero contour.
//
// Lines are drawn per pixel from the distance to the nearest level, estimated to first order as
// |φ − level| / |∇φ| with ∇φ measured in value per pixel. That keeps every line the same width
// in pixels wherever the field is steep or flat, and gives anti-aliasing for free (coverage
// falls off linearly over one pixel at the line's edge), without tracing any curves.
#include <gsd/viz.hpp>

#include "viz/palette.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <sstream>

namespace gsd {
namespace {

constexpr int kDefaultWidth = 512;
constexpr int kMaxSide = 16384;  // pixels per side; far beyond any screen, keeps memory sane
constexpr int kMaxDefaultSide = 4096;  // the default image's longest side, however fine the grid

// The slice plane and the two image axes: u to the right, v up, both in increasing world axis
// order (Z: x, y; Y: x, z; X: y, z).
struct SliceAxes {
    int normal, u, v;
};

SliceAxes slice_axes(Axis axis) {
    switch (axis) {
    case Axis::X: return {0, 1, 2};
    case Axis::Y: return {1, 0, 2};
    case Axis::Z: return {2, 0, 1};
    }
    throw Error("axis", "slice axis must be X, Y or Z");
}

int grid_size(const GridSpec& g, int axis) { return axis == 0 ? g.nx : axis == 1 ? g.ny : g.nz; }

// Where a world coordinate falls between the nodes of one grid axis: the lower node and the
// weight of the upper one (coordinates outside the box clamp to its faces).
struct Lerp {
    int lower;
    double t;
};

Lerp locate(double x, double lo, double hi, int n) {
    const double f = std::clamp((x - lo) / (hi - lo) * (n - 1), 0.0, double(n - 1));
    const int lower = std::min(int(f), n - 2);
    return {lower, f - lower};
}

// The grid values interpolated onto the slice plane at the grid's own (u, v) nodes; bilinear
// sampling of this plane is then exactly trilinear sampling of the grid.
class PlaneField {
public:
    PlaneField(const GridSpec& grid, const std::vector<float>& values, const SliceAxes& ax, double at)
        : nu_(grid_size(grid, ax.u)), nv_(grid_size(grid, ax.v)), data_(std::size_t(nu_) * nv_) {
        const Lerp w = locate(at, grid.box.lo[ax.normal], grid.box.hi[ax.normal], grid_size(grid, ax.normal));
        for (int a = 0; a < nu_; ++a)
            for (int b = 0; b < nv_; ++b) {
                const double v0 = node_value(grid, values, ax, w.lower, a, b);
                const double v1 = node_value(grid, values, ax, w.lower + 1, a, b);
                if (!std::isfinite(v0) || !std::isfinite(v1))
                    throw Error("values", "non-finite value in the grid cells the slice passes through");
                data_[std::size_t(a) * nv_ + b] = (1 - w.t) * v0 + w.t * v1;
            }
    }

    double at(const Lerp& u, const Lerp& v) const {
        const double* row0 = &data_[std::size_t(u.lower) * nv_];
        const double* row1 = row0 + nv_;
        const double low = (1 - v.t) * row0[v.lower] + v.t * row0[v.lower + 1];
        const double high = (1 - v.t) * row1[v.lower] + v.t * row1[v.lower + 1];
        return (1 - u.t) * low + u.t * high;
    }

private:
    static double node_value(const GridSpec& g, const std::vector<float>& values, const SliceAxes& ax,
                             int n, int a, int b) {
        std::array<int, 3> ijk{};
        ijk[ax.normal] = n;
        ijk[ax.u] = a;
        ijk[ax.v] = b;
        return values[(std::size_t(ijk[0]) * g.ny + ijk[1]) * g.nz + ijk[2]];
    }

    int nu_, nv_;
    std::vector<double> data_;
};

// A scalar image, row-major, top row first.
struct FieldImage {
    int width, height;
    std::vector<double> value;
    double operator()(int x, int y) const { return value[std::size_t(y) * width + x]; }
};

FieldImage sample_slice(const PlaneField& plane, const GridSpec& grid, const SliceAxes& ax, int width,
                        int height) {
    const double ulo = grid.box.lo[ax.u], uhi = grid.box.hi[ax.u];
    const double vlo = grid.box.lo[ax.v], vhi = grid.box.hi[ax.v];
    std::vector<Lerp> columns(width), rows(height);
    for (int x = 0; x < width; ++x)  // pixel centers, left to right
        columns[x] = locate(ulo + (x + 0.5) * (uhi - ulo) / width, ulo, uhi, grid_size(grid, ax.u));
    for (int y = 0; y < height; ++y)  // top row is the high end of v
        rows[y] = locate(vhi - (y + 0.5) * (vhi - vlo) / height, vlo, vhi, grid_size(grid, ax.v));
    FieldImage img{width, height, std::vector<double>(std::size_t(width) * height)};
    for (int y = 0; y < height; ++y)
        for (int x = 0; x < width; ++x) img.value[std::size_t(y) * width + x] = plane.at(columns[x], rows[y]);
    return img;
}

// |∇φ| in value per pixel. Per axis it takes the steeper of the two one-sided differences:
// on smooth fields that is the central difference to first order, and across a kink (the
// medial axis of a distance field) it keeps the true slope where a central difference would
// cancel to ~0 and break the lines.
double gradient_per_pixel(const FieldImage& f, int x, int y) {
    double gx = 0, gy = 0;
    if (x > 0) gx = std::abs(f(x, y) - f(x - 1, y));
    if (x + 1 < f.width) gx = std::max(gx, std::abs(f(x + 1, y) - f(x, y)));
    if (y > 0) gy = std::abs(f(x, y) - f(x, y - 1));
    if (y + 1 < f.height) gy = std::max(gy, std::abs(f(x, y + 1) - f(x, y)));
    return std::hypot(gx, gy);
}

using viz::LevelLines;
using viz::Rgb;

viz::LineStyle line_style(int width) {
    const double scale = std::max(1.0, width / double(kDefaultWidth));  // wider images, wider lines
    return {0.5 * scale, 0.55, 1.25 * scale, {25, 25, 25}, {0, 0, 0}, 3.0};
}

Image paint(const FieldImage& f, const SliceOptions& opt) {
    double range = opt.range;
    if (range == 0) {
        for (double v : f.value) range = std::max(range, std::abs(v));
        if (range == 0) range = 1;  // an all-zero slice: any scale shows it as white
    }
    const LevelLines lines(opt.isolines > 0 ? range / opt.isolines : 0.0, opt.zero_contour, line_style(f.width));
    Image img{f.width, f.height, std::vector<std::uint8_t>(std::size_t(f.width) * f.height * 3)};
    for (int y = 0; y < f.height; ++y)
        for (int x = 0; x < f.width; ++x) {
            const double v = f(x, y);
            const Rgb c = lines.draw(viz::diverging(v / range), v, gradient_per_pixel(f, x, y));
            const auto bytes = viz::to_bytes(c);
            std::copy(bytes.begin(), bytes.end(), &img.rgb[(std::size_t(y) * f.width + x) * 3]);
        }
    return img;
}

void check_slice_input(const GridSpec& grid, const std::vector<float>& values, const SliceOptions& opt,
                       const SliceAxes& ax) {
    grid.validate();
    if (values.size() != grid.node_count()) {
        std::ostringstream s;
        s << "grid has " << grid.node_count() << " nodes but " << values.size() << " values were given";
        throw Error("values", s.str());
    }
    const double lo = grid.box.lo[ax.normal], hi = grid.box.hi[ax.normal];
    if (!std::isfinite(opt.at) || opt.at < lo || opt.at > hi) {
        std::ostringstream s;
        s << "slice position " << opt.at << " is outside the grid's box [" << lo << ", " << hi << "]";
        throw Error("at", s.str());
    }
    if (opt.width < 0 || opt.width > kMaxSide) throw Error("width", "image width must be 0 (auto) to 16384");
    if (!std::isfinite(opt.range) || opt.range < 0)
        throw Error("range", "color range must be ≥ 0 (0: auto)");
    if (opt.isolines < 0) throw Error("isolines", "isoline count must be ≥ 0");
}

}  // namespace

Image render_slice(const GridSpec& grid, const std::vector<float>& values, const SliceOptions& opt) {
    const SliceAxes ax = slice_axes(opt.axis);
    check_slice_input(grid, values, opt, ax);
    const Eigen::Vector3d extent = grid.box.extent();
    const double aspect = extent[ax.v] / extent[ax.u];  // square pixels
    int width = opt.width;
    if (width <= 0) {
        // Default: the grid's resolution along the slice (at least 512), but never an image
        // whose sides pass kMaxDefaultSide, however thin or long the grid is.
        const double fit = std::min<double>(kMaxDefaultSide, kMaxDefaultSide / std::max(aspect, 1e-300));
        width = int(std::clamp<double>(std::max(kDefaultWidth, grid_size(grid, ax.u)), 1, std::max(1.0, std::floor(fit))));
    }
    const double height_real = std::round(width * aspect);
    if (!(height_real <= kMaxSide))
        throw Error("width", "slice image would be taller than 16384 pixels; give a smaller width");
    const int height = std::max(1, int(height_real));
    const PlaneField plane(grid, values, ax, opt.at);
    return paint(sample_slice(plane, grid, ax, width, height), opt);
}

}  // namespace gsd
