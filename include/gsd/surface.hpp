// gsd/surface.hpp — geometry *on* a triangle mesh: points and curves on surfaces, and the
// Signed Heat Method on surfaces (thesis ch. 4, §4.3–4.5): geodesic signed distance to curves
// that are broken, open, self-crossing or badly oriented, on meshes that are nonmanifold,
// nonorientable, noisy or holey.
//
//   gsd::SurfaceMesh mesh(gsd::io::read_mesh("bunny.obj"));         // topology, once
//   gsd::SurfaceSources src = gsd::read_surface_sources("heart.txt", mesh);
//   gsd::SignedHeatSurface shm(mesh);                                // operators: lazily, cached
//   gsd::SurfaceShmResult r = shm.solve(src);                        // r.phi per input vertex
//   r = shm.solve(other_curve);                                      // back-substitutions only
//
// Sign convention (the same in every gsd method): φ < 0 on the LEFT of an oriented curve, i.e.
// inside a loop that runs counter-clockwise seen from the side the face normals point to.
// (geometry-central's SignedHeatSolver returns the opposite sign.) docs/shm-surface.md has the
// discretization, the options and measured accuracy and timings.
#pragma once

#include <gsd/export.hpp>

#include <gsd/core.hpp>

#include <array>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

namespace gsd {

namespace mesh {
struct Topology;
}

/// A polygon mesh prepared for surface computations: polygons fan-triangulated, edges numbered.
///
/// Edge numbering (the one curve files use): walk the faces in file order and each face's
/// sides v0→v1, v1→v2, …, v(n−1)→v0; an edge gets the next index the first time its vertex pair
/// is seen, and its first vertex is the tail of that first side. The diagonals added when
/// polygons are triangulated come after all of those. Triangles are numbered in face order
/// (an n-gon gives n−2 consecutive triangles); for a triangle mesh triangle f is face f.
///
/// Nothing is required of the mesh beyond gsd::validate: nonmanifold edges and vertices,
/// inconsistent orientation, boundaries, several components and unreferenced vertices are all
/// allowed. Degenerate (zero-area) triangles are kept in the numbering but carry no area.
/// Copies share the (immutable) topology.
class GSD_EXPORT SurfaceMesh {
public:
    explicit SurfaceMesh(PolygonMesh mesh, const std::string& where = {});

    std::size_t vertex_count() const;
    std::size_t face_count() const;      ///< input faces (polygons)
    std::size_t triangle_count() const;
    std::size_t edge_count() const;      ///< all edges, diagonals included
    std::size_t file_edge_count() const; ///< edges numbered from the faces' sides (curve files)

    /// (first, second) vertex of an edge: its direction for `e i t` points.
    std::array<std::uint32_t, 2> edge(std::size_t e) const;
    /// Vertex indices of a triangle, in the orientation of its input face.
    std::array<std::uint32_t, 3> triangle(std::size_t t) const;
    /// The input face a triangle came from.
    std::uint32_t triangle_face(std::size_t t) const;

    const PolygonMesh& polygons() const;
    /// The triangulated mesh (same vertices) as a PolygonMesh, for writers and renderers.
    PolygonMesh triangles() const;

    /// Surface facts: boundary edges (one triangle), nonmanifold edges (three or more),
    /// edges whose two triangles disagree on orientation, connected components (through edges),
    /// vertices on no triangle, and the Euler characteristic V − E + F of the triangulation.
    struct Summary {
        std::size_t boundary_edges = 0, nonmanifold_edges = 0, misoriented_edges = 0;
        std::size_t components = 0, unreferenced_vertices = 0, degenerate_triangles = 0;
        long long euler_characteristic = 0;
        double mean_edge_length = 0;
    };
    Summary summary() const;

    const mesh::Topology& topology() const { return *topology_; }

private:
    std::shared_ptr<const mesh::Topology> topology_;
};

/// How a point cloud becomes a surface for the surface methods.
struct CloudSurfaceOptions {
    /// Each point's triangles come from the Delaunay triangulation of it and this many nearest
    /// neighbours, projected to its tangent plane. On random sampling a point's Delaunay
    /// neighbours are not always among its 12 nearest: with too few, fans gain triangles that
    /// overlap their neighbours' (measured on a random sphere of 5000 points: ε 2.4× at 12,
    /// 1.0× from 16 on) and the triangulation can gain holes and handles. More only costs
    /// time. 3 to 64.
    int neighbors = 30;
};

/// A point cloud as a surface (thesis fig. 4.5, left; Sharp & Crane 2020, "A Laplacian for
/// nonmanifold triangle meshes"): `mesh` has the cloud's points as its vertices (vertex i is
/// point i) and, as faces, every point's fan of triangles from the Delaunay triangulation of its
/// neighbours in its tangent plane — the union of those fans, nonmanifold where neighbouring
/// fans disagree, which the surface Signed Heat Method takes as it is. `normals` are the fitted
/// tangent planes' unit normals, oriented consistently over each connected piece of the cloud.
/// `triangulation` is a manifold, consistently oriented mesh of the same points, for what needs
/// one (Surface Winding Numbers, level sets, pictures): fan triangles taken greedily, those more
/// fans proposed first, none overlapping another around a point, and the holes left filled up
/// to kMaxFilledHole points around; larger loops are the cloud's own boundary.
struct CloudSurface {
    SurfaceMesh mesh;
    Points normals;
    PolygonMesh triangulation;
};
inline constexpr std::size_t kMaxFilledHole = 32;

/// Builds the surface of a point cloud. `normals` may be empty (an unoriented cloud: each
/// connected piece then faces away from its centroid at its point farthest from it — outward on
/// a closed surface — and a flat piece faces the positive side of the axis nearest its normal) or
/// one per point (only their majority sign per piece is used: noisy or partly flipped normals
/// are fine). Throws gsd::Error for fewer than 3 points, a normal count that differs from the
/// point count, coordinates out of range, or points that span no surface.
GSD_EXPORT CloudSurface cloud_surface(const Points& points, const Points& normals = {},
                                      const CloudSurfaceOptions& options = {}, const std::string& where = {});

/// A point on the surface: a vertex, a point on an edge, or a point inside a triangle.
struct SurfacePoint {
    enum class Kind : std::uint8_t { Vertex, Edge, Face };
    Kind kind = Kind::Vertex;
    std::uint32_t index = 0;  ///< vertex, edge (SurfaceMesh numbering) or triangle
    double u = 0;             ///< Edge: t, the point is (1−t)·first + t·second. Face: weight of corner 1
    double v = 0;             ///< Face: weight of corner 2 (corner 0 has 1 − u − v)

    static SurfacePoint at_vertex(std::uint32_t i) { return {Kind::Vertex, i, 0, 0}; }
    static SurfacePoint on_edge(std::uint32_t e, double t) { return {Kind::Edge, e, t, 0}; }
    static SurfacePoint in_triangle(std::uint32_t t, double u, double v) { return {Kind::Face, t, u, v}; }
};

/// An oriented polyline on the surface. Consecutive nodes may lie in different triangles: the
/// piece between them then follows the shortest path through the triangles that join them.
/// Signed curves carry their orientation (φ < 0 on their left); unsigned curves give distance
/// without a side.
struct SurfaceCurve {
    std::vector<SurfacePoint> nodes;
    bool is_signed = true;
};

/// Everything a solve measures distance to: curves (signed or unsigned) and isolated points
/// (always unsigned). Mixing is allowed (thesis fig. 4.10).
struct SurfaceSources {
    std::vector<SurfaceCurve> curves;
    std::vector<SurfacePoint> points;
    bool empty() const { return curves.empty() && points.empty(); }
};

/// Checks that sources meant for a point cloud (cloud_surface) name its points
/// (SurfacePoint::at_vertex, `v i` in a curve file): edges and triangles would name the ones
/// cloud_surface made, which no file can know. Throws gsd::Error naming `where`.
GSD_EXPORT void require_cloud_points(const SurfaceSources& sources, const std::string& where);

/// Reads curves on a mesh: the curve text format (`v i`, `e i t`, `f i u v`, `l a b c …`,
/// `#offset 0` for 0-based indices, 1-based otherwise; see docs/formats.md) or the `l` lines of
/// an .obj file (1-based vertex indices). Each `l` line becomes one curve; points no line uses
/// are ignored. Errors name the file and line (index out of range, t outside [0, 1], NaN, …).
GSD_EXPORT SurfaceSources read_surface_curves(const std::string& path, const SurfaceMesh& mesh);
/// Reads isolated points: every `v`/`e`/`f` record of a curve text file (lines not allowed),
/// or every vertex named by the `p`/`l` lines of an .obj.
GSD_EXPORT std::vector<SurfacePoint> read_surface_points(const std::string& path, const SurfaceMesh& mesh);
/// Writes curves (and points, as records no line uses) in the curve text format, 0-based
/// (`#offset 0`), atomically. Every node gets its own record; `l` lines join consecutive nodes.
GSD_EXPORT void write_surface_curves(const std::string& path, const SurfaceSources& sources);
/// Checks sources against a mesh (indices in range, finite coordinates in range, ≥ 2 nodes per
/// curve). `where` names the source for the message. Throws gsd::Error.
GSD_EXPORT void validate(const SurfaceSources& sources, const SurfaceMesh& mesh, const std::string& where = {});
/// The 3D position of a surface point.
GSD_EXPORT Eigen::Vector3d position(const SurfaceMesh& mesh, const SurfacePoint& p);

/// Damage to curves for tests and demos, as in thesis fig. 4.16: every curve loses `gaps`
/// stretches holding `cut` of its pieces in all (gaps at random places may overlap, so up to
/// that), then `reversed` single pieces, picked at random, flip their orientation.
struct CurveDamage {
    double cut = 0;
    int gaps = 3;
    int reversed = 0;
};
/// Returns the damaged curves (points kept); deterministic for a seed.
GSD_EXPORT SurfaceSources damage(const SurfaceSources& sources, const CurveDamage& d, std::uint64_t seed);

/// Sources drawn in 3D: each curve as polylines that follow the surface (a piece between nodes
/// in different triangles bends where it crosses edges), each isolated point as a one-point
/// polyline. For pictures and OBJ output.
GSD_EXPORT Polylines source_polylines(const SurfaceMesh& mesh, const SurfaceSources& sources);

/// The level set {f = level} of a per-vertex function (linear on each triangle) as curves whose
/// nodes lie on edges, oriented so that f < level on their left (counter-clockwise around the
/// regions below the level): the zero set of a signed distance comes back as its source curve.
/// Vertices exactly at the level count as above it. Pieces are chained into polylines across
/// triangles that share an edge; closed loops repeat their first node at the end.
GSD_EXPORT std::vector<SurfaceCurve> level_set_curves(const SurfaceMesh& mesh, const std::vector<double>& f, double level = 0);

// ---- the Signed Heat Method on surfaces ---------------------------------------------------

/// How φ is pinned down after integration (thesis §4.4, eq. 4.11, fig. 4.12).
enum class LevelSetConstraint {
    None,        ///< no constraint: φ is shifted so its mean over the curves is zero
    ZeroSet,     ///< φ = 0 at every curve node and point (hard, or soft with a weight)
    Components,  ///< φ constant along each connected curve component (levels found by the solve)
};
GSD_EXPORT LevelSetConstraint level_set_from_name(const std::string& name);  // "none" | "zero" | "components"

/// How step 3 turns the unit field Y into φ.
enum class SurfaceIntegration {
    L2,  ///< least squares ∫|∇φ − Y|² (eq. 4.6): one continuous φ
    L1,  ///< thesis §6.4.1: φ may jump along the cheapest edges where Y cannot be integrated
         ///< (a curve that bounds nothing, around a handle), and is the L² result elsewhere
};
GSD_EXPORT SurfaceIntegration surface_integration_from_name(const std::string& name);  // "l2" | "l1"

/// Per-mesh settings: they decide the operators, which are factored once and cached.
struct SurfaceShmSetup {
    /// Diffusion time t = t_coef · h², h = half the mean edge length (the mean spacing of the
    /// Crouzeix–Raviart nodes, edge midpoints).
    double t_coef = 1.0;
    /// Solve on an intrinsic Delaunay triangulation of the mesh (edge flips; the input mesh is
    /// not changed and φ is reported on its vertices). Improves accuracy on poor triangles.
    bool intrinsic_delaunay = false;
    /// With intrinsic_delaunay: also refine (insert vertices) until no angle is below
    /// `refine_min_angle` degrees, inserting at most `refine_max_vertices` (0: as many as the
    /// mesh has).
    bool refine = false;
    double refine_min_angle = 25.0;
    std::size_t refine_max_vertices = 0;
};

/// Per-solve options.
struct SurfaceShmOptions {
    LevelSetConstraint level_set = LevelSetConstraint::ZeroSet;
    /// Constraint rows are exact where they can be: rows whose points are all vertices (a node
    /// at a vertex, a piece between two vertices), and groups of rows through points on edges
    /// or inside triangles that leave φ a nonzero solution next to the curve (generically: R
    /// rows sharing V vertices, Z of them fixed at 0, with R + Z < V — open curves, curves
    /// broken into pieces). The other groups (closed curves through edge points, corners
    /// inside triangles) would force φ ≡ 0 on every vertex next to the curve, a band of wrong
    /// distances (measured: ε 4–10× larger than unconstrained on exact circles; the reference
    /// implementation behaves the same), so their rows are soft: w·Σ_nodes φ(node)²
    /// (Components: w·Σ_pieces (φ(a) − φ(b))²) is added to the Dirichlet energy, whose matrix
    /// has cotangent weights (entries of order 1). Weights 100–300 stay within 1 % of exact
    /// rows' ε where those are consistent. w = 0 makes every row exact (eq. 4.11 as written).
    /// docs/shm-surface.md has the numbers.
    double soft_weight = 100.0;
    /// Constrain the diffused field to stay normal to the curves at the curves (an extra
    /// constrained vector solve; signed curves only).
    bool preserve_normals = false;
    /// L1: docs/shm-surface.md ("Curves that bound nothing") has the method and measurements.
    /// Runs on the input triangulation (not with SurfaceShmSetup::intrinsic_delaunay).
    SurfaceIntegration integration = SurfaceIntegration::L2;
};

struct SurfaceShmResult {
    std::vector<double> phi;              ///< per input vertex; NaN at vertices on no triangle
    double seconds_factor = 0;            ///< operator assembly and factorizations done by this call
    double seconds_diffuse = 0;           ///< step 1 (sources and vector heat flow)
    double seconds_integrate = 0;         ///< steps 2–3 (normalize, divergence, Poisson, constraints)
    std::size_t constraints = 0;          ///< constraint rows (curve nodes and crossings)
    double constraint_residual = 0;       ///< max |φ(node) − level| after the solve (hard constraints)
    std::size_t constraint_iterations = 0;///< conjugate-gradient steps that made the constraints exact
    std::size_t unreached_vertices = 0;   ///< vertices where the diffused field vanished (no source
                                          ///< in their component): φ there is not a distance
    std::size_t solve_vertices = 0;       ///< vertices of the triangulation solved on (refinement adds)
    std::size_t flips = 0;                ///< intrinsic Delaunay edge flips
    // L1 integration only (empty otherwise):
    std::vector<std::array<double, 3>> corner_phi;  ///< per triangle (SurfaceMesh numbering) and corner:
                                                    ///< φ on either side of a jump (`phi` takes, at a
                                                    ///< vertex on one, the side with the larger angle)
    Polylines jumps;                      ///< the edges φ jumps across, chained
    double jump_cost = 0;                 ///< the L1 program's optimum: Σ weight·∫|jump| over the edges
};

/// Distance sharpening on a surface (thesis §4.4, eq. 4.13): max Σ_v A_v·sign(φ₀)·φ subject to
/// |∇φ| ≤ 1 on every triangle and φ = 0 at the sources' nodes and points, by the primal–dual
/// hybrid gradient method warm-started from φ₀ (a SignedHeatSurface result), restarted to its
/// average (docs/shm-surface.md: distance sharpening). On the CPU, in double.
struct SurfaceSharpenOptions {
    /// PDHG iterations; 0: 24 × the mesh's diameter in edges (its bounding box's diagonal over
    /// the mean edge length).
    int iterations = 0;
    /// Keep every vertex strictly on φ₀'s side (sign(φ₀)·φ > 0), so no inside/outside label
    /// changes. Off: eq. 4.13 as written.
    bool keep_sign = true;
    /// w > 0: the zero set's rows are soft, (w/2)·Σ (φ(node)/h)²; 0: exact. Measured on a
    /// latitude circle through edge points and on polygons across a jittered grid, exact rows
    /// are as good as or better than soft ones (they do not pin φ to 0 next to the curve as
    /// they would in the solve, SurfaceShmOptions::soft_weight: PDHG only bounds the slope).
    double zero_set_weight = 0;
};

struct SurfaceSharpenResult {
    std::vector<double> phi;         ///< per input vertex; NaN where φ₀ is (vertices on no triangle)
    int iterations = 0;
    std::size_t zero_set_rows = 0;   ///< curve nodes and points
    double max_slope = 0;            ///< the largest |∇φ| over the triangles (1 at convergence)
    std::size_t sign_changes = 0;    ///< vertices whose side (φ < 0) differs from φ₀'s
    double seconds = 0;
};

/// Sharpens φ₀ (one value per vertex of `mesh`) against the zero set of `sources`. Throws
/// gsd::Error for a size mismatch, a non-finite φ₀ at a vertex of a triangle, or bad sources.
GSD_EXPORT SurfaceSharpenResult sharpen_distance(const SurfaceMesh& mesh, const std::vector<double>& phi0,
                                                 const SurfaceSources& sources, const SurfaceSharpenOptions& options = {},
                                                 const ProgressFn& progress = {});

/// The surface SHM solver: one per mesh. Operators (Crouzeix–Raviart connection Laplacian and
/// mass matrix, cotan Laplacian) are assembled and factored (CHOLMOD) on the first solve that
/// needs them and reused by every later solve, so a new curve on the same mesh costs
/// back-substitutions. Not thread-safe: use one solver per thread.
class GSD_EXPORT SignedHeatSurface {
public:
    explicit SignedHeatSurface(SurfaceMesh mesh, SurfaceShmSetup setup = {});
    ~SignedHeatSurface();
    SignedHeatSurface(SignedHeatSurface&&) noexcept;
    SignedHeatSurface& operator=(SignedHeatSurface&&) noexcept;

    SurfaceShmResult solve(const SurfaceSources& sources, const SurfaceShmOptions& options = {},
                           const ProgressFn& progress = {});

    /// Distance sharpening of a solve's φ against the same sources (sharpen_distance on this mesh).
    SurfaceSharpenResult sharpen(const std::vector<double>& phi, const SurfaceSources& sources,
                                 const SurfaceSharpenOptions& options = {}, const ProgressFn& progress = {}) const;

    const SurfaceMesh& mesh() const;
    double mean_edge_length() const;  ///< of the triangulation solved on
    double diffusion_time() const;    ///< t

private:
    struct Impl;
    std::unique_ptr<Impl> impl_;
};

}  // namespace gsd

#include <gsd/accuracy.hpp>  // the error measures of thesis §4.5 (surface_distance_error, …)
