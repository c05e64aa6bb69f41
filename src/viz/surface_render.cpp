// Pictures of fields on triangle meshes: a small deterministic software rasterizer.
//
// Two passes, as in a deferred renderer. The raster pass scan-converts every triangle into a
// z-buffer that keeps, per pixel, only the depth and the id of the nearest triangle. The shade
// pass then visits each covered pixel once: it intersects the pixel's ray with that triangle's
// plane and evaluates everything there exactly — the linearly interpolated value, and its
// screen-space gradient in closed form, from which the isolines and the zero contour are drawn
// with the same per-pixel distance estimate as render_slice (so lines are crisp and equally
// wide everywhere, with no curve tracing). Shading work is thus proportional to the image, not
// to the mesh, and a million triangles cost little more than their scan conversion.
//
// Everything is rendered at `supersample`× the final size and box-filtered down at the end,
// which antialiases triangle edges, silhouettes and curves alike.
#include <gsd/viz.hpp>

#include "viz/palette.hpp"

#include <Eigen/Geometry>

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <string>

namespace gsd {
namespace {

using viz::Rgb;
using Vec3 = Eigen::Vector3d;

constexpr int kMaxSide = 16384;
constexpr int kMaxSupersample = 8;
constexpr double kMaxRenderPixels = 1e8;  // width·height·supersample²: ~1.1 GB of buffers
constexpr double kFieldOfView = 30.0 * std::numbers::pi / 180;  // fixes the camera distance
constexpr double kFrameMargin = 0.04;  // of the image on each side around the mesh
constexpr double kAmbient = 0.35;
// Curves are drawn where they are no farther than the surface plus this fraction of the
// mesh's bounding radius: enough for polylines whose chords cut slightly under a curved
// surface, far less than the thickness of any mesh between a front and a back curve.
constexpr double kCurveDepthBias = 0.01;
constexpr double kCurvePieceLength = 32;  // render pixels; keeps each piece's bounding box small
constexpr double kNearPlane = 1e-3;       // curves are clipped this close to the eye, × its distance

// ---- input checks ---------------------------------------------------------------------------

bool finite(const Vec3& v) { return v.allFinite(); }

void check_options(const SurfaceRenderOptions& o) {
    if (o.width < 1 || o.height < 1 || o.width > kMaxSide || o.height > kMaxSide)
        throw Error("size", "image width and height must be 1 to 16384 pixels");
    if (o.supersample < 1 || o.supersample > kMaxSupersample)
        throw Error("supersample", "supersample factor must be 1 to 8");
    const double pixels = double(o.width) * o.height * o.supersample * o.supersample;
    if (pixels > kMaxRenderPixels)
        throw Error("size", "width × height × supersample² is " + std::to_string(std::llround(pixels)) +
                                " pixels; at most 10^8 are rendered");
    if (!finite(o.view_from) || o.view_from.norm() == 0)
        throw Error("view_from", "view direction must be finite and non-zero");
    if (!finite(o.up) || o.view_from.normalized().cross(o.up).norm() <= 1e-9 * o.up.norm())
        throw Error("up", "up vector must be finite, non-zero and not parallel to the view direction");
    if (!std::isfinite(o.range) || o.range < 0) throw Error("range", "color range must be ≥ 0 (0: auto)");
    if (o.isolines < 0) throw Error("isolines", "isoline count must be ≥ 0");
}

void check_picture(const SurfacePicture& p) {
    if (!p.mesh) throw Error("mesh", "surface picture has no mesh");
    validate(*p.mesh, "mesh");
    const std::size_t nv = std::size_t(p.mesh->vertices.rows()), nf = p.mesh->face_count();
    if (!p.vertex_values.empty() && p.vertex_values.size() != nv)
        throw Error("vertex_values", "mesh has " + std::to_string(nv) + " vertices but " +
                                         std::to_string(p.vertex_values.size()) + " values were given");
    if (!p.face_labels.empty() && p.face_labels.size() != nf)
        throw Error("face_labels", "mesh has " + std::to_string(nf) + " faces but " +
                                       std::to_string(p.face_labels.size()) + " labels were given");
    if (!p.vertex_values.empty() && !p.face_labels.empty())
        throw Error("face_labels", "a surface picture shows vertex values or face labels, not both");
    for (const auto& group : p.curves) {
        if (!std::isfinite(group.width) || group.width <= 0) throw Error("curves", "curve width must be positive");
        for (const Polyline& line : group.lines)
            for (const Vec3& point : line)
                if (!finite(point)) throw Error("curves", "curve point with a non-finite coordinate");
    }
}

// ---- geometry -------------------------------------------------------------------------------

// The mesh's polygons fanned into triangles, each remembering its face (for labels).
struct Triangles {
    std::vector<std::array<std::uint32_t, 3>> corners;
    std::vector<std::uint32_t> face;
};

Triangles fan(const PolygonMesh& m) {
    Triangles t;
    const std::size_t count = m.indices.size() - 2 * m.face_count();
    if (count > std::size_t(std::numeric_limits<std::int32_t>::max()))
        throw Error("mesh", "too many triangles to render");
    t.corners.reserve(count);
    t.face.reserve(count);
    for_each_triangle(m, [&](std::size_t f, std::uint32_t a, std::uint32_t b, std::uint32_t c) {
        t.corners.push_back({a, b, c});
        t.face.push_back(std::uint32_t(f));
    });
    return t;
}

Vec3 vertex(const PolygonMesh& m, std::uint32_t v) { return m.vertices.row(v).transpose(); }

// Center and radius of the bounding box of the vertices that faces use (unused vertices, as
// corrupted meshes keep them, must not move the camera).
struct Bounds {
    Vec3 center;
    double radius;
};

Bounds mesh_bounds(const PolygonMesh& m) {
    Vec3 lo = Vec3::Constant(INFINITY), hi = Vec3::Constant(-INFINITY);
    for (std::uint32_t v : m.indices) {
        lo = lo.cwiseMin(vertex(m, v));
        hi = hi.cwiseMax(vertex(m, v));
    }
    const Vec3 center = 0.5 * (lo + hi);
    double radius = 0;
    for (std::uint32_t v : m.indices) radius = std::max(radius, (vertex(m, v) - center).norm());
    return {center, radius > 0 ? radius : 1.0};  // a mesh collapsed to a point: any scale
}

// ---- camera ---------------------------------------------------------------------------------

struct Projected {
    double x, y, z;  // render pixels (y down), depth along the view axis
};

// A pinhole camera in render pixels. The principal point need not be the image center: the
// picture is the crop of a wider view that frames the mesh's silhouette tightly.
struct Camera {
    Vec3 eye, forward, right, up;
    double distance = 1;  // from the eye to the mesh center
    double focal = 1, cx = 0, cy = 0;

    Projected project(const Vec3& p) const {
        const Vec3 q = p - eye;
        const double z = q.dot(forward);
        return {cx + focal * q.dot(right) / z, cy - focal * q.dot(up) / z, z};
    }
    // The ray through render-pixel coordinates (x, y), scaled to unit depth.
    Vec3 ray(double x, double y) const { return forward + ((x - cx) / focal) * right - ((y - cy) / focal) * up; }
};

// Places the eye on the view direction far enough to see the whole bounding sphere, then sets
// focal length and principal point so the projected vertices fill the image less a margin.
Camera frame(const PolygonMesh& m, const Bounds& b, const SurfaceRenderOptions& o, int width, int height) {
    Camera c;
    const Vec3 from = o.view_from.normalized();
    c.forward = -from;
    c.right = c.forward.cross(o.up).normalized();
    c.up = c.right.cross(c.forward);
    c.distance = b.radius / std::sin(kFieldOfView / 2);
    c.eye = b.center + from * c.distance;
    double x0 = INFINITY, x1 = -INFINITY, y0 = INFINITY, y1 = -INFINITY;
    for (std::uint32_t v : m.indices) {  // normalized image-plane coordinates, y up
        const Vec3 q = vertex(m, v) - c.eye;
        const double z = q.dot(c.forward);
        x0 = std::min(x0, q.dot(c.right) / z);
        x1 = std::max(x1, q.dot(c.right) / z);
        y0 = std::min(y0, q.dot(c.up) / z);
        y1 = std::max(y1, q.dot(c.up) / z);
    }
    const double usable = 1 - 2 * kFrameMargin;
    c.focal = std::min(width * usable / std::max(x1 - x0, 1e-12), height * usable / std::max(y1 - y0, 1e-12));
    c.cx = 0.5 * width - c.focal * 0.5 * (x0 + x1);
    c.cy = 0.5 * height + c.focal * 0.5 * (y0 + y1);
    return c;
}

// ---- raster pass ----------------------------------------------------------------------------

// Per render pixel: depth of the nearest surface and which triangle it is (−1: background).
struct Raster {
    int width, height;
    std::vector<float> depth;
    std::vector<std::int32_t> triangle;

    Raster(int w, int h)
        : width(w), height(h), depth(std::size_t(w) * h, INFINITY), triangle(std::size_t(w) * h, -1) {}
    std::size_t index(int x, int y) const { return std::size_t(y) * width + x; }
};

double edge(const Projected& a, const Projected& b, double x, double y) {
    return (b.x - a.x) * (y - a.y) - (b.y - a.y) * (x - a.x);
}

// Scan-converts one triangle: pixels whose centers lie inside (edges included; shared edges
// may be visited twice, the depth test settles it). Depth interpolates as 1/z, which is affine
// in screen space under perspective.
void rasterize_triangle(const std::array<Projected, 3>& p, std::int32_t id, Raster& r) {
    const double area = edge(p[0], p[1], p[2].x, p[2].y);
    if (!(std::abs(area) > 0)) return;  // edge-on or degenerate: covers no pixel center
    const int x0 = std::max(0, int(std::ceil(std::min({p[0].x, p[1].x, p[2].x}) - 0.5)));
    const int x1 = std::min(r.width - 1, int(std::floor(std::max({p[0].x, p[1].x, p[2].x}) - 0.5)));
    const int y0 = std::max(0, int(std::ceil(std::min({p[0].y, p[1].y, p[2].y}) - 0.5)));
    const int y1 = std::min(r.height - 1, int(std::floor(std::max({p[0].y, p[1].y, p[2].y}) - 0.5)));
    if (x0 > x1 || y0 > y1) return;
    const double sign = area > 0 ? 1 : -1, inv_area = 1 / std::abs(area);
    const double iz[3] = {1 / p[0].z, 1 / p[1].z, 1 / p[2].z};
    for (int y = y0; y <= y1; ++y) {
        const double py = y + 0.5;
        for (int x = x0; x <= x1; ++x) {
            const double px = x + 0.5;
            const double w0 = sign * edge(p[1], p[2], px, py), w1 = sign * edge(p[2], p[0], px, py),
                         w2 = sign * edge(p[0], p[1], px, py);
            if (w0 < 0 || w1 < 0 || w2 < 0) continue;
            const float z = float(1 / ((w0 * iz[0] + w1 * iz[1] + w2 * iz[2]) * inv_area));
            const std::size_t i = r.index(x, y);
            if (z < r.depth[i]) {
                r.depth[i] = z;
                r.triangle[i] = id;
            }
        }
    }
}

Raster rasterize(const PolygonMesh& m, const Triangles& t, const Camera& c, int width, int height) {
    std::vector<Projected> projected(std::size_t(m.vertices.rows()));
    for (Eigen::Index v = 0; v < m.vertices.rows(); ++v) projected[std::size_t(v)] = c.project(m.vertices.row(v));
    Raster r(width, height);
    for (std::size_t i = 0; i < t.corners.size(); ++i) {
        const auto& k = t.corners[i];
        rasterize_triangle({projected[k[0]], projected[k[1]], projected[k[2]]}, std::int32_t(i), r);
    }
    return r;
}

// ---- shade pass -----------------------------------------------------------------------------

double auto_range(const std::vector<double>& values, double requested) {
    if (requested > 0) return requested;
    double range = 0;
    for (double v : values)
        if (std::isfinite(v)) range = std::max(range, std::abs(v));
    return range > 0 ? range : 1;  // all zero (or no finite value): any scale shows it
}

Rgb from_bytes(const std::array<std::uint8_t, 3>& c) { return {double(c[0]), double(c[1]), double(c[2])}; }

// The light comes from over the viewer's left shoulder, fixed to the camera so every view is
// lit alike.
Vec3 light_direction(const Camera& c) { return (-c.forward + 0.35 * c.up - 0.25 * c.right).normalized(); }

Rgb times(const Rgb& a, const Rgb& b) { return {a.r * b.r, a.g * b.g, a.b * b.b}; }

// φ at a pixel and |∇φ| there in value per render pixel.
struct Sample {
    double value, gradient;
};

class Shader {
public:
    Shader(const SurfacePicture& p, const SurfaceRenderOptions& o, const Triangles& t, const Camera& c)
        : mesh_(*p.mesh), picture_(p), options_(o), triangles_(t), camera_(c), light_(light_direction(c)),
          range_(auto_range(p.vertex_values, o.range)),
          lines_(o.isolines > 0 ? 2 * range_ / o.isolines : 0.0, o.zero_contour, style(o)) {}

    Rgb pixel(int x, int y, std::int32_t id) const {
        const auto& k = triangles_.corners[std::size_t(id)];
        const Vec3 p0 = vertex(mesh_, k[0]), p1 = vertex(mesh_, k[1]), p2 = vertex(mesh_, k[2]);
        const Vec3 n = (p1 - p0).cross(p2 - p0);
        const Vec3 ray = camera_.ray(x + 0.5, y + 0.5);
        const Rgb light = lighting(n, ray);
        if (!picture_.face_labels.empty())
            return times(from_bytes(label_color(picture_.face_labels[triangles_.face[std::size_t(id)]])), light);
        if (picture_.vertex_values.empty()) return times(viz::kNoValue, light);
        const double f[3] = {picture_.vertex_values[k[0]], picture_.vertex_values[k[1]], picture_.vertex_values[k[2]]};
        const double denom = n.dot(ray);
        if (!std::isfinite(f[0] + f[1] + f[2]) || denom == 0) return times(viz::kNoValue, light);
        const Sample s = sample({p0, p1, p2}, f, n, ray);
        return lines_.draw(times(viz::diverging(s.value / range_), light), s.value, s.gradient);
    }

private:
    // Lines as in render_slice; widths are given in final pixels and scaled to render pixels.
    static viz::LineStyle style(const SurfaceRenderOptions& o) {
        const double s = o.supersample * std::max(1.0, o.width / 1024.0);
        return {0.5 * s, 0.6, 1.25 * s, {25, 25, 25}, {0, 0, 0}, 3.0 * o.supersample};
    }

    // Two-sided Lambert plus ambient, as a per-channel factor. A face seen from behind is lit as
    // if it faced the viewer, and (if asked) tinted yellow-brown: flipped faces and the inside
    // of an open mesh stand out without hiding the field's hue.
    Rgb lighting(const Vec3& n, const Vec3& ray) const {
        const bool back = n.dot(ray) > 0;  // the normal points away from the viewer
        const Vec3 unit = (back ? -n : n).normalized();
        const double l = kAmbient + (1 - kAmbient) * std::max(0.0, unit.dot(light_));
        if (back && options_.mark_back_faces) return {0.92 * l, 0.84 * l, 0.6 * l};
        return {l, l, l};
    }

    // Evaluates φ where the pixel's ray meets the triangle's plane, and its screen gradient in
    // closed form (exact under perspective, so no neighbors are needed and silhouettes and
    // triangle seams cannot corrupt it).
    Sample sample(const std::array<Vec3, 3>& p, const double (&f)[3], const Vec3& n, const Vec3& ray) const {
        // ∇φ in the plane: Σ φ_i (n × e_i) / |n|², e_i the edge opposite corner i.
        const Vec3 grad =
            (f[0] * n.cross(p[2] - p[1]) + f[1] * n.cross(p[0] - p[2]) + f[2] * n.cross(p[1] - p[0])) /
            n.squaredNorm();
        const double denom = n.dot(ray);
        const double t = n.dot(p[0] - camera_.eye) / denom;  // the hit point is eye + t·ray
        const double value = f[0] + grad.dot(camera_.eye + t * ray - p[0]);
        // d(hit)/d(pixel) = t·(dr − ray·(n·dr)/(n·ray)) with dr = d(ray)/d(pixel).
        auto along = [&](const Vec3& dr) { return t * (grad.dot(dr) - grad.dot(ray) * n.dot(dr) / denom); };
        const double gradient = std::hypot(along(camera_.right / camera_.focal), along(-camera_.up / camera_.focal));
        return {value, std::isfinite(gradient) ? gradient : std::numeric_limits<double>::max()};
    }

    const PolygonMesh& mesh_;
    const SurfacePicture& picture_;
    const SurfaceRenderOptions& options_;
    const Triangles& triangles_;
    const Camera& camera_;
    Vec3 light_;
    double range_;
    viz::LevelLines lines_;
};

// Render-resolution colors, 8 bits per channel (enough under the final box filter).
struct Canvas {
    int width, height;
    std::vector<std::uint8_t> rgb;

    void set(std::size_t i, const Rgb& c) {
        const auto b = viz::to_bytes(c);
        std::copy(b.begin(), b.end(), &rgb[3 * i]);
    }
    Rgb get(std::size_t i) const { return {double(rgb[3 * i]), double(rgb[3 * i + 1]), double(rgb[3 * i + 2])}; }
};

Canvas shade(const Raster& r, const Shader& shader, const Rgb& background) {
    Canvas canvas{r.width, r.height, std::vector<std::uint8_t>(std::size_t(r.width) * r.height * 3)};
    for (int y = 0; y < r.height; ++y)
        for (int x = 0; x < r.width; ++x) {
            const std::size_t i = r.index(x, y);
            canvas.set(i, r.triangle[i] < 0 ? background : shader.pixel(x, y, r.triangle[i]));
        }
    return canvas;
}

// ---- curves ---------------------------------------------------------------------------------

// The pixel holding coordinate c, clamped to [−1, size] so that far-off points convert to int.
int pixel_floor(double c, int size) { return int(std::floor(std::clamp(c, -1.0, double(size)))); }

// Draws one group of polylines: the coverage of the whole group is accumulated first (max over
// its segments, so joints are not drawn twice) and blended into the canvas once.
class CurvePainter {
public:
    CurvePainter(const Raster& r, const Camera& c, double bias)
        : raster_(r), camera_(c), bias_(bias), coverage_(r.depth.size(), 0.0f) {}

    void paint(const SurfacePicture::Curves& group, double half_width, Canvas& canvas) {
        for (const Polyline& line : group.lines) {
            if (line.size() == 1) segment(line[0], line[0], half_width);
            for (std::size_t i = 1; i < line.size(); ++i) segment(line[i - 1], line[i], half_width);
        }
        const Rgb color = from_bytes(group.color);
        for (std::size_t i : touched_) {
            canvas.set(i, viz::mix(canvas.get(i), color, coverage_[i]));
            coverage_[i] = 0;
        }
        touched_.clear();
    }

private:
    // Clips to the space in front of the camera, projects, and draws in short pieces. The near
    // plane sits at a small fraction of the mesh's distance: what is nearer would fill the view,
    // and projected coordinates stay small enough for int pixel indices.
    void segment(Vec3 a, Vec3 b, double half_width) {
        const double near = kNearPlane * camera_.distance;
        const double za = (a - camera_.eye).dot(camera_.forward), zb = (b - camera_.eye).dot(camera_.forward);
        if (za < near && zb < near) return;
        if (za < near) a += (b - a) * ((near - za) / (zb - za));
        if (zb < near) b += (a - b) * ((near - zb) / (za - zb));
        const Projected pa = camera_.project(a), pb = camera_.project(b);
        double s0 = 0, s1 = 1;
        if (!clip_to_image(pa, pb, half_width + 2, s0, s1)) return;
        // Along a projected line 1/z is affine in screen position, so pieces interpolate it.
        auto at = [&](double s) {
            return Projected{pa.x + s * (pb.x - pa.x), pa.y + s * (pb.y - pa.y), 1 / ((1 - s) / pa.z + s / pb.z)};
        };
        const double length = (s1 - s0) * std::hypot(pb.x - pa.x, pb.y - pa.y);
        const int pieces = std::max(1, int(std::ceil(length / kCurvePieceLength)));
        for (int i = 0; i < pieces; ++i)
            capsule(at(s0 + (s1 - s0) * i / pieces), at(s0 + (s1 - s0) * (i + 1) / pieces), half_width);
    }

    // Narrows [s0, s1] to the part of the screen segment a–b inside the image grown by
    // `margin` (Liang–Barsky); false if none is. Bounds the work for segments that leave the view.
    bool clip_to_image(const Projected& a, const Projected& b, double margin, double& s0, double& s1) const {
        const double dx = b.x - a.x, dy = b.y - a.y;
        auto keep = [&](double p, double q) {  // keeps the s with p·s ≤ q
            if (p == 0) return q >= 0;
            const double r = q / p;
            if (p < 0) s0 = std::max(s0, r);
            else s1 = std::min(s1, r);
            return s0 <= s1;
        };
        return keep(-dx, a.x + margin) && keep(dx, raster_.width + margin - a.x) && keep(-dy, a.y + margin) &&
               keep(dy, raster_.height + margin - a.y);
    }

    // All render pixels within half_width of the screen segment a–b, where the segment is not
    // behind the surface.
    void capsule(const Projected& a, const Projected& b, double half_width) {
        const double reach = half_width + 1;
        const int x0 = pixel_floor(std::min(a.x, b.x) - reach, raster_.width);
        const int x1 = pixel_floor(std::max(a.x, b.x) + reach, raster_.width);
        const int y0 = pixel_floor(std::min(a.y, b.y) - reach, raster_.height);
        const int y1 = pixel_floor(std::max(a.y, b.y) + reach, raster_.height);
        const double dx = b.x - a.x, dy = b.y - a.y, len2 = dx * dx + dy * dy;
        for (int y = std::max(y0, 0); y <= std::min(y1, raster_.height - 1); ++y)
            for (int x = std::max(x0, 0); x <= std::min(x1, raster_.width - 1); ++x) {
                const double px = x + 0.5, py = y + 0.5;
                const double s = len2 > 0 ? std::clamp(((px - a.x) * dx + (py - a.y) * dy) / len2, 0.0, 1.0) : 0.0;
                const double qx = a.x + s * dx, qy = a.y + s * dy;
                const double cov = viz::line_coverage(std::hypot(px - qx, py - qy), half_width);
                const std::size_t i = raster_.index(x, y);
                if (cov <= coverage_[i]) continue;
                if (!visible(qx, qy, 1 / ((1 - s) / a.z + s / b.z))) continue;
                if (coverage_[i] == 0) touched_.push_back(i);
                coverage_[i] = float(cov);
            }
    }

    // A curve point shows unless the surface around it (the farthest of the 3×3 pixels about
    // it, so that steep surfaces near a silhouette do not swallow curves lying on them) is
    // nearer to the camera than the point by more than the bias.
    bool visible(double qx, double qy, double z) const {
        const int cx = int(std::floor(qx)), cy = int(std::floor(qy));
        float farthest = -INFINITY;
        for (int y = cy - 1; y <= cy + 1; ++y)
            for (int x = cx - 1; x <= cx + 1; ++x) {
                if (x < 0 || y < 0 || x >= raster_.width || y >= raster_.height) return true;
                farthest = std::max(farthest, raster_.depth[raster_.index(x, y)]);
            }
        return z <= double(farthest) + bias_;
    }

    const Raster& raster_;
    const Camera& camera_;
    double bias_;
    std::vector<float> coverage_;
    std::vector<std::size_t> touched_;
};

// ---- output ---------------------------------------------------------------------------------

Image downsample(const Canvas& c, int factor) {
    Image img{c.width / factor, c.height / factor, {}};
    img.rgb.resize(std::size_t(img.width) * img.height * 3);
    const double weight = 1.0 / (factor * factor);
    for (int y = 0; y < img.height; ++y)
        for (int x = 0; x < img.width; ++x)
            for (int ch = 0; ch < 3; ++ch) {
                int sum = 0;
                for (int dy = 0; dy < factor; ++dy)
                    for (int dx = 0; dx < factor; ++dx)
                        sum += c.rgb[3 * (std::size_t(y * factor + dy) * c.width + std::size_t(x * factor + dx)) + ch];
                img.rgb[3 * (std::size_t(y) * img.width + x) + ch] = viz::to_byte(sum * weight);
            }
    return img;
}

}  // namespace

Image render_surface(const SurfacePicture& picture, const SurfaceRenderOptions& options) {
    check_options(options);
    check_picture(picture);
    const PolygonMesh& mesh = *picture.mesh;
    const int ss = options.supersample, width = options.width * ss, height = options.height * ss;
    const Triangles triangles = fan(mesh);
    const Bounds bounds = mesh_bounds(mesh);
    const Camera camera = frame(mesh, bounds, options, width, height);
    const Raster raster = rasterize(mesh, triangles, camera, width, height);
    Canvas canvas = shade(raster, Shader(picture, options, triangles, camera), from_bytes(options.background));
    if (!picture.curves.empty()) {
        CurvePainter painter(raster, camera, kCurveDepthBias * bounds.radius);
        for (const auto& group : picture.curves) painter.paint(group, 0.5 * group.width * ss, canvas);
    }
    return downsample(canvas, ss);
}

std::array<std::uint8_t, 3> label_color(int label) {
    // Tableau 10 without its gray (gray means "no value" here); +1, −1, +2, −2, … in turn.
    static constexpr std::array<Rgb, 9> kCycle{{
        {31, 119, 180}, {255, 127, 14}, {44, 160, 44}, {214, 39, 40}, {148, 103, 189},
        {140, 86, 75}, {227, 119, 194}, {188, 189, 34}, {23, 190, 207},
    }};
    if (label == 0) return {238, 236, 230};
    const long long k = label > 0 ? 2LL * label - 1 : -2LL * label;  // 1, 2, 3, …
    const Rgb base = kCycle[std::size_t((k - 1) % 9)];
    const long long round = (k - 1) / 9;  // later rounds: darker, then lighter, alternating
    if (round == 0) return viz::to_bytes(base);
    if (round % 2 == 1) return viz::to_bytes({base.r * 0.6, base.g * 0.6, base.b * 0.6});
    return viz::to_bytes(viz::mix(base, {255, 255, 255}, 0.45));
}

}  // namespace gsd
