// gsd/baselines.hpp — the classic convolutional signed distances the thesis compares PAT with
// (§5.3): smoothed signed planar distance (SSPD, eq. 5.9) and signed Hopf–Cole (SHC, eq. 5.8).
// Both blend per-point terms exactly like PAT (same summed set and λ, BlendOptions), weighted
// by each point's area A_i = π d_8² / 8 (gsd::point_areas).
#pragma once

#include <gsd/export.hpp>

#include <gsd/core.hpp>
#include <gsd/blend.hpp>
#include <gsd/field.hpp>

#include <memory>

namespace gsd {

enum class Baseline {
    Sspd,  ///< Σ A_i ⟨x − p_i, n_i⟩ w_i / Σ A_i w_i
    Shc,   ///< sign(w)(−log|w|/λ + σ_x), w the screened dipole sum
};

/// A baseline signed distance field over an oriented cloud. Gradients are not offered
/// (with_gradient is an error).
class GSD_EXPORT BaselineField final : public Field {
public:
    BaselineField(Baseline kind, const PointCloud& cloud, BlendOptions options = {});
    ~BaselineField() override;
    BaselineField(BaselineField&&) noexcept;
    BaselineField& operator=(BaselineField&&) noexcept;

    using Field::evaluate;  // the float32 overload
    FieldValues evaluate(PointsView queries, bool with_gradient = false,
                         const ProgressFn& progress = {}) const override;
    FieldValues evaluate(const GridSpec& grid, bool with_gradient = false,
                         const ProgressFn& progress = {}) const override;
    bool has_gradient() const override { return false; }
    /// The blend's kernel (gpu::evaluate_into, φ only).
    const DeviceProgram* device_program() const override;
    double r_eval() const;

private:
    struct Impl;
    std::unique_ptr<Impl> impl_;
};

/// Parses "sspd" / "shc".
GSD_EXPORT Baseline baseline_from_name(const std::string& name);

}  // namespace gsd
