// Booleans, offsets and shells of fields (gsd/field_algebra.hpp). An operator evaluates its
// operands over the whole domain — a grid as a grid, so each operand takes its own grid path —
// and combines their values (and gradients) query by query.
#include <gsd/field_algebra.hpp>

#include "field/composite.hpp"

#include <algorithm>
#include <cmath>
#include <string>
#include <utility>

namespace gsd {

namespace field {

void OperatorField::flatten_operand(const Field& f, std::vector<CombineOp>& ops, std::vector<const Field*>& leaves) {
    if (const auto* op = dynamic_cast<const OperatorField*>(&f)) return op->flatten(ops, leaves);
    ops.push_back({float(kLeaf), float(leaves.size()), 0});
    leaves.push_back(&f);
}

const DeviceProgram* OperatorField::device_program() const {
    std::call_once(once_, [&] {
        std::vector<CombineOp> ops;
        std::vector<const Field*> leaves;
        flatten(ops, leaves);
        int depth = 0, deepest = 0;
        for (const CombineOp& op : ops) {
            const int code = int(op.code);
            depth += code == kLeaf ? 1 : code <= kDifference ? -1 : 0;
            deepest = std::max(deepest, depth);
        }
        const bool any = std::any_of(leaves.begin(), leaves.end(), [](const Field* f) { return f->device_program() != nullptr; });
        if (any && deepest <= kMaxStack) program_ = make_composite_program(std::move(ops), std::move(leaves));
    });
    return program_.get();
}

#if !defined(GSD_HAVE_VULKAN)
std::shared_ptr<const DeviceProgram> make_composite_program(std::vector<CombineOp>, std::vector<const Field*>) { return nullptr; }
#endif

}  // namespace field

namespace {

void check_operand(const FieldPtr& f, const char* which) {
    if (!f) throw Error(which, "is null: an operator needs a field");
}

// The device line of a result made of two: one name when both ran in one place.
std::string devices(const std::string& a, const std::string& b) { return a == b ? a : a + ", " + b; }

// The progress of one of two operands evaluated in turn, as half of the operator's.
ProgressFn half(const ProgressFn& progress, int which) {
    if (!progress) return {};
    return [progress, which](std::string_view stage, double fraction) { progress(stage, 0.5 * (which + fraction)); };
}

// min, max and a − b as one: σ·min(σa·a, σb·b) (max(a, b) = −min(−a, −b), a − b = max(a, −b)).
struct BooleanSigns {
    double a, b, result;
    const char* name;
    field::OpCode code;  // the device's
};
constexpr BooleanSigns kUnion{1, 1, 1, "union", field::kUnion}, kIntersection{-1, -1, -1, "intersection", field::kIntersection},
    kDifference{-1, 1, -1, "difference", field::kDifference};

class BooleanField final : public field::OperatorField {
public:
    BooleanField(FieldPtr a, FieldPtr b, BooleanSigns signs, double smooth)
        : a_(std::move(a)), b_(std::move(b)), signs_(signs), smooth_(smooth) {
        check_operand(a_, "first operand");
        check_operand(b_, "second operand");
        if (!(smooth_ >= 0 && std::isfinite(smooth_)))
            throw Error("smooth", "must be a finite radius ≥ 0 (0: the sharp " + std::string(signs_.name) + ")");
    }

    using Field::evaluate;
    FieldValues evaluate(PointsView q, bool with_gradient, const ProgressFn& progress) const override {
        return combined(q, with_gradient, progress);
    }
    FieldValues evaluate(const GridSpec& grid, bool with_gradient, const ProgressFn& progress) const override {
        return combined(grid, with_gradient, progress);
    }
    bool has_gradient() const override { return a_->has_gradient() && b_->has_gradient(); }
    void flatten(std::vector<field::CombineOp>& ops, std::vector<const Field*>& leaves) const override {
        flatten_operand(*a_, ops, leaves);
        flatten_operand(*b_, ops, leaves);
        ops.push_back({float(signs_.code), 0, float(smooth_)});
    }

private:
    template <class Domain>
    FieldValues combined(const Domain& domain, bool with_gradient, const ProgressFn& progress) const {
        refuse_gradient(with_gradient && !has_gradient(), "Booleans of a field without ∇φ");
        FieldValues a = a_->evaluate(domain, with_gradient, half(progress, 0));
        const FieldValues b = b_->evaluate(domain, with_gradient, half(progress, 1));
        const std::size_t n = a.phi.size();
        if (b.phi.size() != n) throw Error(signs_.name, "its operands returned different numbers of values");
        const double k = smooth_;
#pragma omp parallel for schedule(static)
        for (std::ptrdiff_t i = 0; i < std::ptrdiff_t(n); ++i) {
            const double u = signs_.a * a.phi[std::size_t(i)], v = signs_.b * b.phi[std::size_t(i)];
            // The smooth minimum's weight on the larger operand, 0 where |u − v| ≥ k.
            const double h = k > 0 ? std::max(k - std::abs(u - v), 0.0) : 0.0;
            const double s = k > 0 ? h / (2 * k) : 0.0;
            const double m = std::min(u, v) - (k > 0 ? h * h / (4 * k) : 0.0);
            a.phi[std::size_t(i)] = float(signs_.result * m);
            if (!with_gradient) continue;
            const double wa = (u <= v ? 1 - s : s) * signs_.a * signs_.result, wb = (u <= v ? s : 1 - s) * signs_.b * signs_.result;
            for (std::size_t c = 0; c < 3; ++c) {
                const std::size_t j = 3 * std::size_t(i) + c;
                a.gradient[j] = float(wa * a.gradient[j] + wb * b.gradient[j]);
            }
        }
        a.device = devices(a.device, b.device);
        return a;
    }

    FieldPtr a_, b_;
    BooleanSigns signs_;
    double smooth_;
};

// φ − r, or |φ| − r (a shell).
class OffsetField final : public field::OperatorField {
public:
    OffsetField(FieldPtr a, double r, bool shell) : a_(std::move(a)), r_(r), shell_(shell) {
        check_operand(a_, shell ? "shell" : "offset");
        if (!std::isfinite(r_) || (shell_ && r_ < 0))
            throw Error(shell_ ? "shell" : "offset", shell_ ? "the half thickness must be a finite number ≥ 0"
                                                             : "the distance must be a finite number");
    }

    using Field::evaluate;
    FieldValues evaluate(PointsView q, bool with_gradient, const ProgressFn& progress) const override {
        return shifted(a_->evaluate(q, with_gradient, progress), with_gradient);
    }
    FieldValues evaluate(const GridSpec& grid, bool with_gradient, const ProgressFn& progress) const override {
        return shifted(a_->evaluate(grid, with_gradient, progress), with_gradient);
    }
    bool has_gradient() const override { return a_->has_gradient(); }
    void flatten(std::vector<field::CombineOp>& ops, std::vector<const Field*>& leaves) const override {
        flatten_operand(*a_, ops, leaves);
        ops.push_back({float(shell_ ? field::kShell : field::kOffset), 0, float(r_)});
    }

private:
    FieldValues shifted(FieldValues v, bool with_gradient) const {
#pragma omp parallel for schedule(static)
        for (std::ptrdiff_t i = 0; i < std::ptrdiff_t(v.phi.size()); ++i) {
            float& phi = v.phi[std::size_t(i)];
            const bool flip = shell_ && phi < 0;
            phi = float((flip ? -double(phi) : double(phi)) - r_);
            if (with_gradient && flip)
                for (std::size_t c = 0; c < 3; ++c) v.gradient[3 * std::size_t(i) + c] = -v.gradient[3 * std::size_t(i) + c];
        }
        return v;
    }

    FieldPtr a_;
    double r_;
    bool shell_;
};

}  // namespace

FieldPtr field_union(FieldPtr a, FieldPtr b, double smooth) {
    return std::make_shared<BooleanField>(std::move(a), std::move(b), kUnion, smooth);
}
FieldPtr field_intersection(FieldPtr a, FieldPtr b, double smooth) {
    return std::make_shared<BooleanField>(std::move(a), std::move(b), kIntersection, smooth);
}
FieldPtr field_difference(FieldPtr a, FieldPtr b, double smooth) {
    return std::make_shared<BooleanField>(std::move(a), std::move(b), kDifference, smooth);
}
FieldPtr field_offset(FieldPtr a, double r) { return std::make_shared<OffsetField>(std::move(a), r, false); }
FieldPtr field_shell(FieldPtr a, double r) { return std::make_shared<OffsetField>(std::move(a), r, true); }

}  // namespace gsd
