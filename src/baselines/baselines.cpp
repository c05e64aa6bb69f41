#include <gsd/baselines.hpp>
#include <gsd/spatial.hpp>

#include "blend/blend.hpp"

namespace gsd {

struct BaselineField::Impl {
    blend::Engine engine;
    blend::EngineProgram program{engine, false, "the SSPD and signed Hopf–Cole baselines"};
    static blend::Source source_of(Baseline kind, const PointCloud& cloud) {
        if (cloud.size() < 2) throw Error("a baseline field needs at least 2 points");
        blend::Source s;
        s.kind = kind == Baseline::Sspd ? blend::Kind::Sspd : blend::Kind::Shc;
        s.points = cloud.points;
        s.normals = cloud.normals;
        KdTree tree(s.points);
        s.spacing = mean_spacing(tree);
        s.areas = point_areas(tree);
        return s;
    }
    Impl(Baseline kind, const PointCloud& cloud, BlendOptions opt) : engine(source_of(kind, cloud), std::move(opt)) {}
};

BaselineField::BaselineField(Baseline kind, const PointCloud& cloud, BlendOptions options)
    : impl_(std::make_unique<Impl>(kind, cloud, std::move(options))) {}
BaselineField::~BaselineField() = default;
BaselineField::BaselineField(BaselineField&&) noexcept = default;
BaselineField& BaselineField::operator=(BaselineField&&) noexcept = default;

FieldValues BaselineField::evaluate(PointsView queries, bool with_gradient, const ProgressFn& progress) const {
    refuse_gradient(with_gradient, "the SSPD and signed Hopf–Cole baselines");
    if (!queries.allFinite()) throw Error("queries", "query points must be finite");
    return impl_->engine.evaluate(blend::Queries(queries), false, progress);
}

FieldValues BaselineField::evaluate(const GridSpec& grid, bool with_gradient, const ProgressFn& progress) const {
    refuse_gradient(with_gradient, "the SSPD and signed Hopf–Cole baselines");
    grid.validate();
    return impl_->engine.evaluate(blend::Queries(grid), false, progress);
}

const DeviceProgram* BaselineField::device_program() const { return &impl_->program; }

double BaselineField::r_eval() const { return impl_->engine.r_eval(); }

Baseline baseline_from_name(const std::string& name) {
    if (name == "sspd") return Baseline::Sspd;
    if (name == "shc") return Baseline::Shc;
    throw Error("baseline", "unknown baseline '" + name + "' (sspd, shc)");
}

}  // namespace gsd
