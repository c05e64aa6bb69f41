// The blend engine shared by PAT and the convolutional baselines (SSPD, signed Hopf–Cole):
// every one of them sums per-point terms with weights exp(−λ(‖x − p_i‖ − σ)) over the same
// set of points, chosen by the same rule (BlendOptions). Private to the library.
#pragma once

#include <gsd/gpu.hpp>
#include <gsd/pat.hpp>
#include <gsd/spatial.hpp>

#include "spatial/box_tree.hpp"

#include <algorithm>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

namespace gsd {
class BaselineField;
}

namespace gsd::gpu {
class Recorder;
class Buffer;
}  // namespace gsd::gpu

namespace gsd::blend {

enum class Kind { Pat = 0, Sspd = 1, Shc = 2 };

/// Per-point data of a blended field. Pat uses tori (built in double on the CPU, and on the
/// device from `tangents` and `jets`); Sspd and Shc use normals and areas.
struct Source {
    Kind kind = Kind::Pat;
    Points points;
    Points normals;
    Points tangents;
    std::vector<Jet> jets;
    std::vector<Torus> tori;
    std::vector<double> areas;
    double spacing = 0;  ///< mean nearest-neighbor spacing h
};

/// The resolved parameters of the set rule (see BlendOptions).
struct Params {
    bool exact = false;
    double r_eval = 0;
    int fallback_k = 32;
    double C = 64;
    bool gradient = false;
};
Params resolve(const BlendOptions& opt, const Source& src, bool gradient);

/// Where queries come from: an explicit list or the nodes of a grid (generated on the fly so
/// a 512³ grid never materializes as doubles).
class Queries {
public:
    /// Keeps a pointer to the view's data: the view (and whatever it refers to, or the copy a
    /// Ref made of a differently laid-out matrix) must outlive this object.
    explicit Queries(const PointsView& p) : points_(p.data()), rows_(std::size_t(p.rows())), stride_(std::size_t(p.outerStride())) {}
    explicit Queries(const GridSpec& g) : grid_(g) {}
    std::size_t size() const { return points_ ? rows_ : grid_.node_count(); }
    Eigen::Vector3d at(std::size_t i) const;
    /// An explicit list (not a grid)?, and then the list itself.
    bool is_list() const { return points_ != nullptr; }
    /// The grid (when not a list).
    const GridSpec& grid() const { return grid_; }
    PointsView list() const {
        return PointsView(Eigen::Map<const Points, 0, Eigen::OuterStride<>>(points_, Eigen::Index(rows_), 3, Eigen::OuterStride<>(Eigen::Index(stride_))));
    }

private:
    const double* points_ = nullptr;  // row i at points_[i·stride_], not owned
    std::size_t rows_ = 0, stride_ = 3;
    GridSpec grid_;
};

/// Output arrays: phi has one float per query; gradient (may be null) three.
struct Output {
    float* phi;
    float* gradient;
};

/// The taper of the accelerated sum, T(v) = (1 − v²)³ + 1e-9 for v = d/ρ ∈ [0, 1]: it makes a
/// point's weight vanish (to 1e-9) as it reaches the edge of the summed set, so φ stays
/// continuous where the set changes. The 1e-9 floor keeps Σw > 0 when every point sits at ρ.
inline double blend_taper(double v) {
    const double a = 1 - std::min(v * v, 1.0);
    return a * a * a + 1e-9;
}
inline double blend_taper_derivative(double v) {
    const double a = 1 - std::min(v * v, 1.0);
    return -6 * v * a * a;
}

/// CPU reference (double precision, OpenMP). The tree indexes src.points.
void evaluate_cpu(const Source& src, const spatial::BoxTree& tree, const Params& params, const Queries& queries,
                  Output out, const ProgressFn& progress);

/// One query on the CPU; exposed for tests. Returns φ and writes ∇φ if `grad` is set.
double evaluate_one(const Source& src, const spatial::BoxTree& tree, const Params& params,
                    const Eigen::Vector3d& x, Eigen::Vector3d* grad, std::vector<Neighbor>& scratch);

class GpuField;  // device-side copy of a Source (blend_gpu.cpp)
class Engine;

/// Builds a GpuField on a context, or returns null and a reason when the source does not fit
/// the device (buffer range, memory) or the parameters exceed what the kernel supports.
std::shared_ptr<GpuField> make_gpu_field(const std::shared_ptr<gpu::Context>& ctx, const Source& src,
                                         const spatial::BoxTree& tree, const Params& params, std::string& why_not);
std::string gpu_field_device(const GpuField& field);
const gpu::Context* gpu_field_context(const GpuField& field);
/// Records the renderer's render_pat kernel over a field's device data (src/render): rays
/// [first_pixel, first_pixel + pixel_count) of the camera in `params` (tile order), hits into
/// `hits`, `rays_per_lane` rays for each invocation; `loop_cap`: render_march.glsl's LOOP_CAP;
/// `empty`: the empty cells' bits (render.hpp's EmptySpace; any buffer when params say none).
void record_render(GpuField& field, gpu::Recorder& rec, const Params& p, const gpu::Buffer& params,
                   const gpu::Buffer& empty, const gpu::Buffer& hits, std::uint32_t first_pixel, std::uint32_t pixel_count,
                   std::uint32_t rays_per_lane, std::uint32_t loop_cap);
void evaluate_gpu(GpuField& field, const Params& params, const Queries& queries, Output out,
                  std::size_t chunk_size, const ProgressFn& progress);
/// Builds the kernel evaluate_gpu runs for these parameters now (thread-safe: another thread
/// may evaluate meanwhile), so that a later evaluation finds it made.
void prepare_gpu(GpuField& field, const Params& params);

/// Tori built on the device by the torus_from_jet kernel (12 floats each: q, k1, e1, k2, n, 0),
/// for conformance tests.
std::vector<float> tori_on_device(gpu::Context& ctx, const Points& points, const Points& normals,
                                  const Points& tangents, const std::vector<Jet>& jets);

/// A Source plus its lazily built search structures on each path: the object a public field
/// (TorusField, SspdField, ShcField) holds.
class Engine {
public:
    Engine(Source src, BlendOptions opt);
    ~Engine();
    FieldValues evaluate(const Queries& q, bool gradient, const ProgressFn& progress) const;
    /// The source on a given device (an adopted one, say), uploaded on first use and kept;
    /// throws gsd::Error when it does not fit there.
    std::shared_ptr<GpuField> on_device(const std::shared_ptr<gpu::Context>& ctx) const;
    Params params(bool gradient) const { return resolve(opt_, src_, gradient); }
    /// The kd-tree over the source's points (built on first use).
    const spatial::BoxTree& search_tree() const { return tree(); }
    const Source& source() const { return src_; }
    const BlendOptions& options() const { return opt_; }
    double r_eval() const { return resolve(opt_, src_, false).r_eval; }

private:
    const spatial::BoxTree& tree() const;
    Source src_;
    BlendOptions opt_;
    // Built on first use; the mutex makes concurrent evaluate() calls safe.
    mutable std::mutex init_mutex_;
    mutable std::unique_ptr<spatial::BoxTree> tree_;
    mutable std::shared_ptr<GpuField> gpu_;
    mutable bool gpu_tried_ = false;
    mutable std::vector<std::shared_ptr<GpuField>> placed_;  // on_device(), one per context
};

}  // namespace gsd::blend

namespace gsd::blend {

/// The device program of a field that is a blend (TorusField, BaselineField: Field::device_program):
/// evaluate_into through the engine's placement on the context. The renderer finds the engine
/// through it for its own march (render_pat).
class EngineProgram final : public DeviceProgram {
public:
    /// `what`: the field's name for a refused gradient; `gradient`: whether it offers ∇φ.
    EngineProgram(const Engine& engine, bool gradient, const char* what) : engine_(engine), gradient_(gradient), what_(what) {}
    void evaluate_into(const std::shared_ptr<gpu::Context>& context, const gpu::DeviceQueries& job,
                       const gpu::SubmitSync& sync) const override;
    const Engine& engine() const { return engine_; }

private:
    const Engine& engine_;
    bool gradient_;
    const char* what_;
};

}  // namespace gsd::blend
