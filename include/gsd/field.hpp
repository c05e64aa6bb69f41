// gsd/field.hpp — the one shape every evaluable field has: queries in, φ (and ∇φ) out.
//
//   const gsd::Field& f = torus_field;            // or a BaselineField, or a WindingField
//   gsd::FieldValues v = f.evaluate(points, /*with_gradient=*/f.has_gradient());
//   gsd::FieldValues g = f.evaluate(gsd::GridSpec::cube(64, box));
//
// PAT (TorusField, gsd/pat.hpp), the convolutional baselines (BaselineField,
// gsd/baselines.hpp) and generalized winding numbers (WindingField, gsd/sums.hpp) implement it,
// so code that samples a field — a grid writer, a renderer, a training-data generator — takes
// a `const Field&` and works with all of them. Queries come as double (PointsView: a Points or
// a map over the caller's memory, no copy) or float32 (PointsFView).
#pragma once

#include <gsd/export.hpp>

#include <gsd/core.hpp>

#include <memory>
#include <string>
#include <vector>

namespace gsd {

namespace gpu {
class Context;
struct DeviceQueries;
struct SubmitSync;
}  // namespace gpu

/// A field's evaluation on a Vulkan device: what gpu::evaluate_into and the renderer run there
/// (gsd/vulkan.hpp defines the job and sync types). A field offers one through
/// Field::device_program(); the program is owned by the field and valid while it lives.
class GSD_EXPORT DeviceProgram {
public:
    virtual ~DeviceProgram();
    /// Evaluates `job.count` queries on the device into `job.results` (gpu::evaluate_into's
    /// contract: gsd/vulkan.hpp).
    virtual void evaluate_into(const std::shared_ptr<gpu::Context>& context, const gpu::DeviceQueries& job,
                               const gpu::SubmitSync& sync) const = 0;

protected:
    DeviceProgram() = default;
    DeviceProgram(const DeviceProgram&) = default;
    DeviceProgram& operator=(const DeviceProgram&) = default;
};

/// Result of an evaluation.
struct FieldValues {
    std::vector<float> phi;       ///< one value per query
    std::vector<float> gradient;  ///< 3 per query (x, y, z), if asked for
    std::string device;           ///< the device that computed them ("cpu" or the Vulkan device name)
};

class GSD_EXPORT Field {
public:
    virtual ~Field();

    /// φ at every query (and ∇φ if `with_gradient`; a field without gradients throws
    /// gsd::Error "with_gradient" then). Non-finite queries are an error. A Points, a block of
    /// one or an Eigen::Map over the caller's doubles is read in place.
    virtual FieldValues evaluate(PointsView queries, bool with_gradient = false,
                                 const ProgressFn& progress = {}) const = 0;
    /// float32 queries, converted to double once (fields compute in double on the CPU).
    FieldValues evaluate(PointsFView queries, bool with_gradient = false, const ProgressFn& progress = {}) const;
    /// φ on every node of a grid, in GridSpec storage order.
    virtual FieldValues evaluate(const GridSpec& grid, bool with_gradient = false,
                                 const ProgressFn& progress = {}) const = 0;
    /// Whether evaluate() can return ∇φ.
    virtual bool has_gradient() const = 0;
    /// The field's program on a Vulkan device, or nullptr (the default): gpu::evaluate_into and
    /// the renderer then evaluate it with evaluate() on the CPU, with one line saying so. PAT and
    /// the baselines have one (in a build with Vulkan), and so has every composite of
    /// gsd/field_algebra.hpp: its leaves evaluate into device buffers (each by its own program,
    /// or on the CPU) and one pass combines them.
    virtual const DeviceProgram* device_program() const { return nullptr; }

protected:
    /// Throws Error("with_gradient", …) when a gradient is asked of a field without one.
    static void refuse_gradient(bool with_gradient, const char* field_kind);

    Field() = default;
    Field(const Field&) = default;
    Field(Field&&) = default;
    Field& operator=(const Field&) = default;
    Field& operator=(Field&&) = default;
};

}  // namespace gsd
