// gsd/shapes.hpp — analytic shapes with exact signed distance and area-uniform sampling.
//
// These are the ground truth for accuracy tests and the source of the project's own demo
// data (`gsd sample`). Every shape knows its exact SDF (negative inside) and can draw
// points uniformly by area together with exact outward normals.
#pragma once

#include <gsd/export.hpp>

#include <gsd/core.hpp>

#include <cstdint>
#include <memory>
#include <string>

namespace gsd::shapes {

class GSD_EXPORT Shape {
public:
    virtual ~Shape() = default;
    virtual std::string name() const = 0;
    /// Exact signed distance, negative inside.
    virtual double sdf(const Eigen::Vector3d& x) const = 0;
    /// Total surface area.
    virtual double area() const = 0;
    /// `n` points uniformly distributed by area, with exact outward unit normals.
    /// Deterministic for a given seed.
    virtual PointCloud sample(std::size_t n, std::uint64_t seed) const = 0;
};

GSD_EXPORT std::unique_ptr<Shape> sphere(const Eigen::Vector3d& center, double radius);
/// Ring torus around the z axis through `center`: major radius R, minor radius r (r < R).
GSD_EXPORT std::unique_ptr<Shape> torus(const Eigen::Vector3d& center, double R, double r);
/// Capsule: all points within `radius` of the segment a–b.
GSD_EXPORT std::unique_ptr<Shape> capsule(const Eigen::Vector3d& a, const Eigen::Vector3d& b, double radius);
/// Axis-aligned box with half extents `half` (the core box), rounded by `radius`: all points
/// within `radius` of the core box.
GSD_EXPORT std::unique_ptr<Shape> rounded_box(const Eigen::Vector3d& center, const Eigen::Vector3d& half,
                                   double radius);

/// Looks a shape up by name with the defaults used by tests and the demo, all inside
/// [−1, 1]³: "sphere" (r 0.5), "torus" (R 0.5, r 0.2), "capsule" (±0.4 on x, r 0.3),
/// "rounded-box" (half 0.35 0.25 0.2, r 0.15). Throws on an unknown name.
GSD_EXPORT std::unique_ptr<Shape> by_name(const std::string& name);

/// Damage to apply to a clean sampling (thesis §7.2 corruptions). All fractions in [0, 1].
struct Corruption {
    double position_noise = 0;  ///< Gaussian σ on positions, in units of the bounding-box diagonal
    double normal_noise = 0;    ///< Gaussian σ added to unit normals before renormalizing
    double flip_fraction = 0;   ///< fraction of normals negated
    double outlier_fraction = 0;///< fraction of points replaced by uniform points in the bounding box
    int holes = 0;              ///< number of holes cut (points removed within a radius of random centers)
    double hole_radius = 0.15;  ///< hole radius in units of the bounding-box diagonal
};
/// Returns a corrupted copy (deterministic for a given seed). Never returns fewer than 2 points.
GSD_EXPORT PointCloud corrupt(const PointCloud& clean, const Corruption& c, std::uint64_t seed);

/// A closed triangle mesh of a shape: the zero level set of its exact SDF, contoured on an
/// n³ grid over the shape's bounding box (enlarged by 4 cells). Oriented outward.
GSD_EXPORT PolygonMesh mesh(const Shape& shape, int n);

/// Damage to a mesh, as in thesis §4.4 / fig. 4.16: large holes, flipped faces, noise.
struct MeshCorruption {
    int holes = 0;              ///< number of holes, cut around random faces
    double hole_area = 0.2;     ///< total fraction of the surface area the holes remove
    double flip_fraction = 0;   ///< fraction of the remaining faces whose orientation is reversed
    double vertex_noise = 0;    ///< Gaussian σ on vertex positions, × bounding-box diagonal
};
/// Returns a damaged copy (deterministic for a seed); unused vertices are kept.
GSD_EXPORT PolygonMesh corrupt(const PolygonMesh& mesh, const MeshCorruption& c, std::uint64_t seed);

/// A flat triangle mesh of the square [−half, half]² in the plane z = 0 (test and demo domain for
/// the surface methods): n × n squares, each split along a diagonal (directions alternate, or are
/// random when `random_diagonals`), interior vertices jittered by up to `jitter` × the cell
/// size. Faces are counter-clockwise seen from +z. Deterministic for a seed.
GSD_EXPORT PolygonMesh grid_mesh(int n, double jitter = 0, bool random_diagonals = false, std::uint64_t seed = 0,
                      double half = 1.0);

/// A sphere as an icosahedron whose faces are split 1→4 `level` times (20·4^level triangles),
/// vertices pushed onto the sphere; faces oriented outward.
GSD_EXPORT PolygonMesh icosphere(int level, double radius = 1.0, const Eigen::Vector3d& center = Eigen::Vector3d::Zero());

/// A ring torus around the z axis (major radius R, tube radius r), n_major × n_minor vertices on
/// its parameter grid, each grid cell split in two; faces oriented outward. Genus 1.
GSD_EXPORT PolygonMesh torus_mesh(int n_major, int n_minor, double R = 0.5, double r = 0.2);

/// A double torus (genus 2): two tori (R 0.5, r 0.2) around the z axis with centers (±0.425, 0, 0)
/// whose tubes merge, contoured on an n³ grid over [−1.3, 1.3]³; oriented outward.
GSD_EXPORT PolygonMesh double_torus_mesh(int n);

/// Total area of a mesh's faces (polygons fanned).
GSD_EXPORT double area(const PolygonMesh& mesh);

}  // namespace gsd::shapes
