#include <gsd/pat.hpp>

#include "blend/blend.hpp"

namespace gsd {

struct TorusField::Impl {
    FittedTori tori;
    blend::Engine engine;

    static blend::Source source_of(const FittedTori& t) {
        blend::Source s;
        s.kind = blend::Kind::Pat;
        s.points = t.points;
        s.normals = t.normals;
        s.tangents = t.tangents;
        s.jets = t.jets;
        s.tori = t.tori();
        s.spacing = t.spacing;
        return s;
    }
    Impl(FittedTori t, BlendOptions opt) : tori(std::move(t)), engine(source_of(tori), std::move(opt)) {}
};

TorusField::TorusField(FittedTori tori, BlendOptions options) {
    if (tori.size() < 2) throw Error("PAT needs at least 2 fitted points");
    if (tori.jets.size() != std::size_t(tori.size()) || tori.normals.rows() != tori.size() ||
        tori.tangents.rows() != tori.size())
        throw Error("fitted tori have inconsistent counts");
    impl_ = std::make_unique<Impl>(std::move(tori), std::move(options));
}

TorusField::~TorusField() = default;
TorusField::TorusField(TorusField&&) noexcept = default;
TorusField& TorusField::operator=(TorusField&&) noexcept = default;

FieldValues TorusField::evaluate(const Points& queries, bool with_gradient, const ProgressFn& progress) const {
    if (!queries.allFinite()) throw Error("queries", "query points must be finite");
    return impl_->engine.evaluate(blend::Queries(queries), with_gradient, progress);
}

FieldValues TorusField::evaluate(const GridSpec& grid, bool with_gradient, const ProgressFn& progress) const {
    grid.validate();
    return impl_->engine.evaluate(blend::Queries(grid), with_gradient, progress);
}

const FittedTori& TorusField::tori() const { return impl_->tori; }
const BlendOptions& TorusField::options() const { return impl_->engine.options(); }
double TorusField::r_eval() const { return impl_->engine.r_eval(); }

}  // namespace gsd
