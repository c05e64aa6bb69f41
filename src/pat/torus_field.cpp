#include <gsd/pat.hpp>
#include <gsd/spatial.hpp>

#include "blend/blend.hpp"
#include "pat/outliers.hpp"

namespace gsd {

namespace {

// The blend's source: every torus, or only the trusted ones. The spacing (which scales the
// evaluation radius) is that of the blended points, so outliers, which sit far from everything,
// do not inflate it.
blend::Source source_of(const FittedTori& t, std::vector<Torus> all, const PointConfidence& conf) {
    blend::Source s;
    s.kind = blend::Kind::Pat;
    std::vector<Eigen::Index> keep;
    keep.reserve(std::size_t(t.size()));
    for (Eigen::Index i = 0; i < t.size(); ++i)
        if (conf.score.empty() || !conf.is_outlier(std::size_t(i))) keep.push_back(i);
    const auto m = Eigen::Index(keep.size());
    s.points.resize(m, 3);
    s.normals.resize(m, 3);
    s.tangents.resize(m, 3);
    for (Eigen::Index r = 0; r < m; ++r) {
        const Eigen::Index i = keep[std::size_t(r)];
        s.points.row(r) = t.points.row(i);
        s.normals.row(r) = t.normals.row(i);
        s.tangents.row(r) = t.tangents.row(i);
        s.jets.push_back(t.jets[std::size_t(i)]);
        s.tori.push_back(std::move(all[std::size_t(i)]));
    }
    s.spacing = m == t.size() ? t.spacing : mean_spacing(s.points);
    return s;
}

}  // namespace

struct TorusField::Impl {
    FittedTori tori;
    OutlierOptions outliers;
    PointConfidence confidence;
    blend::Engine engine;
    blend::EngineProgram program{engine, true, "PAT fields"};

    // `all` = t.tori(), built once for the scores and the blend.
    Impl(FittedTori t, std::vector<Torus> all, BlendOptions opt, OutlierOptions out)
        : tori(std::move(t)),
          outliers(out),
          confidence(out.enabled ? pat::score_points(tori, all, out) : PointConfidence{}),
          engine(source_of(tori, std::move(all), confidence), std::move(opt)) {}
};

TorusField::TorusField(FittedTori tori, BlendOptions options, OutlierOptions outliers) {
    if (tori.size() < 2) throw Error("PAT needs at least 2 fitted points");
    if (tori.jets.size() != std::size_t(tori.size()) || tori.normals.rows() != tori.size() ||
        tori.tangents.rows() != tori.size())
        throw Error("fitted tori have inconsistent counts");
    // Measured: 477 B per point at 10⁶, 490 B from 10⁶ to 10⁷ (the tori, the blend's tree, the
    // outlier scores); docs/io.md.
    check_memory(576.0 * double(tori.size()), "tori", "a torus field of " + std::to_string(tori.size()) + " points");
    std::vector<Torus> all = tori.tori();
    impl_ = std::make_unique<Impl>(std::move(tori), std::move(all), std::move(options), outliers);
}

TorusField::~TorusField() = default;
TorusField::TorusField(TorusField&&) noexcept = default;
TorusField& TorusField::operator=(TorusField&&) noexcept = default;

FieldValues TorusField::evaluate(PointsView queries, bool with_gradient, const ProgressFn& progress) const {
    if (!queries.allFinite()) throw Error("queries", "query points must be finite");
    return impl_->engine.evaluate(blend::Queries(queries), with_gradient, progress);
}

FieldValues TorusField::evaluate(const GridSpec& grid, bool with_gradient, const ProgressFn& progress) const {
    grid.validate();
    return impl_->engine.evaluate(blend::Queries(grid), with_gradient, progress);
}

const DeviceProgram* TorusField::device_program() const { return &impl_->program; }

const FittedTori& TorusField::tori() const { return impl_->tori; }
const PointConfidence& TorusField::confidence() const { return impl_->confidence; }
Eigen::Index TorusField::blended_count() const { return impl_->engine.source().points.rows(); }
const BlendOptions& TorusField::options() const { return impl_->engine.options(); }
const OutlierOptions& TorusField::outlier_options() const { return impl_->outliers; }
double TorusField::r_eval() const { return impl_->engine.r_eval(); }

}  // namespace gsd
