// gsd/pat.hpp — Points as Tori (thesis ch. 5): generalized signed distance from an oriented
// point cloud by blending the signed distance functions of tori fitted at every point.
//
//   gsd::JetFitter fitter;                        // or gsd::TorusNet (the learned fitter)
//   gsd::FittedTori tori = fitter.fit(cloud);     // once per cloud (save/load with the .tori format)
//   gsd::TorusField field(tori);                  // options: exact sum, device, radius
//   auto phi = field.evaluate(queries);           // φ at any points; gradients on request
#pragma once

#include <gsd/export.hpp>

#include <gsd/core.hpp>
#include <gsd/field.hpp>
#include <gsd/blend.hpp>
#include <gsd/gpu.hpp>

#include <array>
#include <memory>
#include <string>
#include <vector>

namespace gsd {

// ---- tori from local height functions ---------------------------------------------------

/// The six coefficients of the height function Q(s,t) = a00 + a10 s + a01 t + a11 st + a20 s²
/// + a02 t² that describes the surface near a point along its normal, in the point's tangent
/// frame (s, t, n).
struct Jet {
    double a00 = 0, a10 = 0, a01 = 0, a11 = 0, a20 = 0, a02 = 0;
};

/// A torus in the curvature form that stays finite in the flat and cylindrical limits.
/// `q` lies on the torus; `n` is the outward unit normal there; `e1` is the principal
/// direction of `k1` (the curvature of larger magnitude) and is parallel to the torus axis.
/// Curvatures are signed with respect to `n`: k < 0 bends away from n (convex, like the
/// outside of a sphere), k > 0 bends toward it (concave). Minor radius r = 1/|k1|; the
/// tube's center is q + n/k1 and the torus's center q + n/k2; k1 = k2 = 0 is a plane.
struct GSD_EXPORT Torus {
    Eigen::Vector3d q = Eigen::Vector3d::Zero();
    Eigen::Vector3d e1 = Eigen::Vector3d::UnitX();
    Eigen::Vector3d n = Eigen::Vector3d::UnitZ();
    double k1 = 0, k2 = 0;
};

/// The classic parameters of a torus (thesis eq. 5.3): center c, unit axis u, major radius R,
/// minor radius r, and the sign that makes g = sign·φ_T increase along the outward normal.
/// Only defined when k1 ≠ 0 (a plane has no finite torus form); a cylinder has R = ∞.
struct TorusGeometry {
    Eigen::Vector3d c, u;
    double R, r, sign;
};
GSD_EXPORT TorusGeometry geometry(const Torus& t);

/// A tangent frame for a unit normal n: returns s with s ⟂ n, |s| = 1; t = n × s. The choice
/// is deterministic (it defines the coordinates the jet coefficients are expressed in).
GSD_EXPORT Eigen::Vector3d tangent_of(const Eigen::Vector3d& n);

/// Builds the osculating torus of the height function `jet` at point p with unit normal n and
/// tangent s (t = n × s): the surface point q = p + a00 n, normal, principal curvatures and
/// directions from the first and second fundamental forms (II v = κ I v).
GSD_EXPORT Torus torus_from_jet(const Eigen::Vector3d& p, const Eigen::Vector3d& n, const Eigen::Vector3d& s,
                     const Jet& jet);

/// Signed distance g(x) of the torus, positive on the side its normal points to; optionally its
/// gradient. Evaluated in a form that is exact for tori and stays accurate in float32 as the
/// radii grow (planes and cylinders are its limits).
GSD_EXPORT double torus_sdf(const Torus& t, const Eigen::Vector3d& x, Eigen::Vector3d* gradient = nullptr);

// ---- fitting ------------------------------------------------------------------------------

/// The result of fitting: per point, the frame and coefficients that define its torus.
/// This is what the .tori file stores, so a cloud is fitted once.
struct GSD_EXPORT FittedTori {
    Points points;               ///< p_i
    Points normals;              ///< n_i (unit)
    Points tangents;             ///< s_i (unit, ⟂ n_i); t_i = n_i × s_i
    std::vector<Jet> jets;       ///< coefficients in the frame (s_i, t_i, n_i)
    double spacing = 0;          ///< mean nearest-neighbor spacing h of the cloud
    std::string fitter;          ///< which fitter made them ("jet", "net")

    Eigen::Index size() const { return points.rows(); }
    /// The torus of point i.
    Torus torus(Eigen::Index i) const;
    std::vector<Torus> tori() const;
};

/// Saves/loads the documented binary .tori format (docs/formats.md). Loading validates
/// everything (magic, version, counts against the file size, finite values).
GSD_EXPORT void save_tori(const std::string& path, const FittedTori& tori);
GSD_EXPORT FittedTori load_tori(const std::string& path);

struct JetFitterOptions {
    /// Neighbors per fit, the point itself included.
    int k = 24;
    /// Gaussian weight exp(−d²/σ²) with σ = sigma_factor × (distance to the k-th neighbor).
    double sigma_factor = 1.0;
    /// Weight of the slope rows that make the fit match neighbor normals (Hermite fit),
    /// relative to the height rows; 0 fits positions only (the classic jet).
    double normal_weight = 1.0;
    /// Neighbors whose normal makes an angle over this with n_i don't give slope rows
    /// (their height function would be steep or flipped).
    double max_normal_angle_deg = 60.0;
};

/// Weighted least-squares quadratic over the k nearest neighbors in each point's tangent frame
/// (thesis fig. 5.17's classic baseline, here with optional normal rows). Multi-threaded.
class GSD_EXPORT JetFitter {
public:
    explicit JetFitter(JetFitterOptions options = {});
    /// Fits every point of a validated cloud. Reports progress as ("fit", fraction).
    FittedTori fit(const PointCloud& cloud, const ProgressFn& progress = {}) const;
    const JetFitterOptions& options() const { return options_; }

private:
    JetFitterOptions options_;
};

/// Where it runs and the points per GPU chunk: Execution (gsd/gpu.hpp).
struct TorusNetOptions : Execution {
    /// Weights file (.safetensors, docs/torusnet.md); empty: the model shipped in the library
    /// (models/torusnet.safetensors, embedded at build time).
    std::string model;
};

/// TorusNet (thesis §5.1.2, docs/torusnet.md): a small transformer reads each point's k nearest
/// neighbors (k fixed by the model) in the point's tangent frame and predicts the six jet
/// coefficients the jet fit would solve for. Runs on the device chosen by `options.device`
/// (float32 kernels) or on the CPU reference (double, multi-threaded); a device that was
/// selected but fails is an error, not a silent fallback. Copies share the loaded model.
class GSD_EXPORT TorusNet {
public:
    /// Loads and validates the model (throws gsd::Error naming the file on any problem).
    explicit TorusNet(TorusNetOptions options = {});
    /// Predicts every point of a validated cloud with at least k() points (fitter "net").
    /// Reports progress as ("fit", fraction).
    FittedTori fit(const PointCloud& cloud, const ProgressFn& progress = {}) const;
    /// Neighbors per point, the point itself included.
    int k() const;
    /// The model's architecture and its free-form description, in one line.
    std::string description() const;
    const TorusNetOptions& options() const;

private:
    struct Impl;
    std::shared_ptr<const Impl> impl_;
};

// ---- outliers -----------------------------------------------------------------------------

/// PAT's defence against outliers (docs/pat.md, "Outliers"). Each point gets two measures:
/// - its residual: how far it lies from the tori of its k nearest neighbors (the `quantile` of
///   those distances), in units of the neighbors' own spacing ℓ (the median of their distances
///   to their k-th neighbor). A point on the surface lies on its neighbors' tori up to noise;
///   a stray point near the surface does not.
/// - its sparsity: its own ℓ over the cloud's median ℓ. Stray points far from the surface have
///   only each other as neighbors, which are many times farther apart than surface samples.
/// A point whose residual exceeds max(min_score, median + mad_factor·MAD of the cloud's
/// residuals), or whose sparsity exceeds max(sparsity_factor, median + mad_factor·MAD of the
/// cloud's sparsities), is an outlier and is left out of the blend.
struct OutlierOptions {
    /// Leave outliers out of the blend (TorusField). false: every point is blended, as in the
    /// thesis (for comparison).
    bool enabled = true;
    /// Neighbors whose tori judge each point.
    int k = 16;
    /// Which order statistic of the k distances is the score: a low one, so a point needs only
    /// some of its neighbors' surfaces through it (edges, thin parts, holes).
    double quantile = 0.25;
    /// The smallest threshold, in neighbor spacings: on a clean cloud nothing is dropped.
    double min_score = 0.35;
    /// The thresholds grow with the spread of the cloud's residuals (its noise level) and
    /// sparsities (how unevenly it is sampled).
    double mad_factor = 8.0;
    /// The smallest sparsity threshold: a point whose k-th neighbor is this many times farther
    /// than the cloud's median is an outlier (a region that much sparser holds
    /// sparsity_factor² times fewer samples per area).
    double sparsity_factor = 3.0;
};

/// Per-point outlier scores and confidences of fitted tori.
struct PointConfidence {
    std::vector<double> score;      ///< residual: distance to the neighbors' tori, in their spacings
    std::vector<double> sparsity;   ///< distance to the k-th neighbor over the cloud's median
    /// 1 / (1 + r⁴) with r = max(score/threshold, sparsity/sparsity_threshold): 1 trusted, ½ at
    /// a threshold, → 0 far beyond.
    std::vector<float> confidence;
    double threshold = 0;           ///< the residual above which a point is an outlier
    double sparsity_threshold = 0;  ///< the sparsity above which a point is an outlier
    std::size_t outliers = 0;       ///< how many points are outliers

    bool is_outlier(std::size_t i) const { return score[i] > threshold || sparsity[i] > sparsity_threshold; }
};

/// Scores every point (multi-threaded; O(n k log n)). Clouds with at most k points are all
/// trusted (confidence 1). Throws gsd::Error naming the option field on bad options.
GSD_EXPORT PointConfidence point_confidence(const FittedTori& tori, const OutlierOptions& options = {});

/// The cloud without its outliers: jets fitted (JetFitter's defaults), scored by
/// point_confidence, the outliers left out. For methods that
/// take a cloud as it is (the SHM's sources): PAT's blend leaves them out by itself.
/// `dropped`, if given, receives how many went.
GSD_EXPORT PointCloud without_outliers(const PointCloud& cloud, const OutlierOptions& options = {},
                                       std::size_t* dropped = nullptr);

// ---- evaluation ---------------------------------------------------------------------------

/// The PAT signed distance field of a set of fitted tori.
class GSD_EXPORT TorusField final : public Field {
public:
    /// Scores the points (point_confidence) unless `outliers.enabled` is false, and blends the
    /// ones that are not outliers.
    explicit TorusField(FittedTori tori, BlendOptions options = {}, OutlierOptions outliers = {});
    ~TorusField() override;
    TorusField(TorusField&&) noexcept;
    TorusField& operator=(TorusField&&) noexcept;

    /// φ (and ∇φ if `with_gradient`) at every query point.
    using Field::evaluate;  // the float32 overload
    FieldValues evaluate(PointsView queries, bool with_gradient = false,
                         const ProgressFn& progress = {}) const override;
    /// φ on every node of a grid, in GridSpec storage order.
    FieldValues evaluate(const GridSpec& grid, bool with_gradient = false,
                         const ProgressFn& progress = {}) const override;
    bool has_gradient() const override { return true; }
    /// The blend's kernel (gpu::evaluate_into, the renderer's own march).
    const DeviceProgram* device_program() const override;

    /// All the fitted tori, outliers included.
    const FittedTori& tori() const;
    /// The points' scores and confidences (empty vectors when the defence is disabled).
    const PointConfidence& confidence() const;
    /// How many points the blend uses (the tori that are not outliers).
    Eigen::Index blended_count() const;
    const BlendOptions& options() const;
    const OutlierOptions& outlier_options() const;
    /// The radius of the accelerated sum actually used.
    double r_eval() const;

private:
    struct Impl;
    std::unique_ptr<Impl> impl_;
};

}  // namespace gsd
