// Opening and closing of a field's shape (gsd/field_algebra.hpp): offsets on a grid with a
// re-distancing between them, so that the second offset acts on a true distance. The
// re-distancing measures the exact distance to the first offset's zero set, meshed by marching
// cubes, with the nearest-triangle search of gsd sdf.
#include <gsd/field_algebra.hpp>
#include <gsd/sdf.hpp>
#include <gsd/viz.hpp>

#include <cmath>
#include <mutex>

namespace gsd {

std::vector<float> redistance(const GridSpec& grid, const std::vector<float>& values) {
    grid.validate();
    if (values.size() != grid.node_count())
        throw Error("values", std::to_string(values.size()) + " values for a grid of " + std::to_string(grid.node_count()) + " nodes");
    const PolygonMesh zero_set = contour(grid, values, 0.0);
    std::vector<float> out(values.size());
    if (zero_set.face_count() == 0) {  // no surface in the grid: as far as the grid reaches
        const auto far = float(grid.box.diagonal());
        for (std::size_t i = 0; i < values.size(); ++i) out[i] = values[i] < 0 ? -far : far;
        return out;
    }
    MeshSdfOptions o;
    o.sign = SdfSign::none;
    o.device = "cpu";  // exact distances; the nodes' signs are the values'
    const std::vector<double> d = mesh_sdf(zero_set, grid.nodes(), o).phi;
    for (std::size_t i = 0; i < values.size(); ++i) out[i] = float(values[i] < 0 ? -d[i] : d[i]);
    return out;
}

namespace {

class MorphologyField final : public Field {
public:
    MorphologyField(FieldPtr a, double r, bool opening, const GridSpec& grid) : a_(std::move(a)), r_(r), opening_(opening), grid_(grid) {
        const char* name = opening ? "opening" : "closing";
        if (!a_) throw Error(name, "is null: an operator needs a field");
        if (!(r_ > 0 && std::isfinite(r_))) throw Error(name, "the radius must be a finite number > 0");
        grid_.validate();
        check_memory(48.0 * double(grid_.node_count()), name, "a grid of " + std::to_string(grid_.node_count()) + " nodes");
    }

    using Field::evaluate;
    FieldValues evaluate(PointsView q, bool with_gradient, const ProgressFn& progress) const override {
        return solved(progress).evaluate(q, with_gradient);
    }
    FieldValues evaluate(const GridSpec& grid, bool with_gradient, const ProgressFn& progress) const override {
        return solved(progress).evaluate(grid, with_gradient);
    }
    bool has_gradient() const override { return true; }

private:
    // Opening: φ + r (eroded), re-distanced, − r (dilated); closing the other way round.
    const GridField& solved(const ProgressFn& progress) const {
        std::call_once(once_, [&] {
            std::vector<float> v = a_->evaluate(grid_, false, progress).phi;
            const float first = float(opening_ ? r_ : -r_);
            for (float& x : v) x += first;
            v = redistance(grid_, v);
            for (float& x : v) x -= first;
            result_ = std::make_unique<GridField>(grid_, std::move(v));
        });
        return *result_;
    }

    FieldPtr a_;
    double r_;
    bool opening_;
    GridSpec grid_;
    mutable std::once_flag once_;
    mutable std::unique_ptr<GridField> result_;
};

}  // namespace

FieldPtr field_opening(FieldPtr a, double r, const GridSpec& grid) {
    return std::make_shared<MorphologyField>(std::move(a), r, true, grid);
}
FieldPtr field_closing(FieldPtr a, double r, const GridSpec& grid) {
    return std::make_shared<MorphologyField>(std::move(a), r, false, grid);
}

}  // namespace gsd
