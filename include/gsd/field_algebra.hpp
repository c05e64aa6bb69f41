// gsd/field_algebra.hpp — fields made of fields: Booleans, offsets and shells of any gsd::Field
// (PAT, the baselines, winding numbers, a mesh's exact signed distance, a grid read back), and a
// grid's values as a field (docs/field.md).
//
//   gsd::FieldPtr a = std::make_shared<gsd::TorusField>(gsd::load_tori("scan.tori"));
//   gsd::FieldPtr b = std::make_shared<gsd::GridField>(grid, values);
//   gsd::FieldPtr both = gsd::field_union(a, gsd::field_offset(b, 0.05));
//   gsd::FieldValues v = both->evaluate(gsd::GridSpec::cube(64, box), /*with_gradient=*/true);
//
// Each operator evaluates its operands over the whole domain (a grid stays a grid, so each
// operand takes its own fast grid path) and combines them node by node. Every operator is
// 1-Lipschitz in its operands (docs/field.md: the bounds), so a composite of distance-like fields
// is as safe to sphere-trace as its operands.
#pragma once

#include <gsd/export.hpp>
#include <gsd/field.hpp>

#include <memory>
#include <vector>

namespace gsd {

using FieldPtr = std::shared_ptr<const Field>;

/// A grid's values (φ, GridSpec storage order) as a field: trilinear between the nodes, ∇φ the
/// interpolant's gradient. Outside the grid's box: the value at the nearest point of the box
/// plus the distance to it (a 1-Lipschitz grid stays 1-Lipschitz; far queries read as outside).
class GSD_EXPORT GridField final : public Field {
public:
    /// Throws gsd::Error for an invalid grid, a value count that is not its node count, or a
    /// non-finite value.
    GridField(GridSpec grid, std::vector<float> values);

    using Field::evaluate;
    FieldValues evaluate(PointsView queries, bool with_gradient = false, const ProgressFn& progress = {}) const override;
    /// On its own grid the values as they are; on another, sampled as at points.
    FieldValues evaluate(const GridSpec& grid, bool with_gradient = false, const ProgressFn& progress = {}) const override;
    bool has_gradient() const override { return true; }

    const GridSpec& grid() const { return grid_; }
    const std::vector<float>& values() const { return values_; }

private:
    GridSpec grid_;
    std::vector<float> values_;
};

/// Union (min), intersection (max) and difference (a minus b: max(a, −b)) of two fields. With
/// `smooth` = k > 0, the polynomial smooth minimum, min(a, b) − max(k − |a − b|, 0)²/(4k): equal
/// to the sharp one where |a − b| ≥ k, at most k/4 below it, its gradient a convex combination of
/// the operands' (so never steeper than the steeper of them). ∇ of the sharp ones: the chosen
/// operand's. Throws gsd::Error for a null operand or a negative or non-finite `smooth`.
GSD_EXPORT FieldPtr field_union(FieldPtr a, FieldPtr b, double smooth = 0);
GSD_EXPORT FieldPtr field_intersection(FieldPtr a, FieldPtr b, double smooth = 0);
GSD_EXPORT FieldPtr field_difference(FieldPtr a, FieldPtr b, double smooth = 0);
/// φ − r: the level set at distance r outside (r > 0) or inside (r < 0) the surface. Exact on a
/// true signed distance; on a generalized one, as exact as the field is at distance r.
GSD_EXPORT FieldPtr field_offset(FieldPtr a, double r);
/// |φ| − r: a shell of thickness 2r about the surface (r ≥ 0).
GSD_EXPORT FieldPtr field_shell(FieldPtr a, double r);

/// Opening (erosion by r, then dilation by r: removes what is thinner than 2r) and closing
/// (dilation, then erosion: fills gaps narrower than 2r) of a field's shape, after thesis
/// figs. 4.9 and 5.7. On `grid`: the field's values there are offset by ±r, re-distanced
/// (redistance below) so that the second offset acts on a true distance, and offset back; the
/// result is that grid as a GridField (trilinear). Computed at the first evaluation and kept.
/// Throws gsd::Error for a null field, r ≤ 0 or non-finite, or an invalid grid.
GSD_EXPORT FieldPtr field_opening(FieldPtr a, double r, const GridSpec& grid);
GSD_EXPORT FieldPtr field_closing(FieldPtr a, double r, const GridSpec& grid);

/// Opening and closing without a grid or a mesh, for a field whose zero set has sample points
/// (a cloud's own: `seeds`). The first offset's zero set is sampled: each seed moves by r along
/// ∓∇φ (an opening's erosion: inward) and is projected onto φ = ∓r by Newton steps, and is kept
/// where it lands on it about r from the nearest seed (where that surface does not exist — a fin
/// thinner than 2r, a slot narrower than 2r — it crosses over and lands near the other side's
/// seeds). The offset field is then re-distanced at each query without a grid: sign(φ ± r) times
/// the distance to those samples (each a disk of half the seeds' spacing, normal to ∇φ), and the
/// second offset applied on top. Sign from the field, distance from the samples: the error it
/// adds is the samples' (docs/field.md: morphology). Sampled at the first evaluation and kept;
/// evaluated on the CPU (a kd-tree per query) after the field itself. Throws gsd::Error for a
/// null field, a field without ∇φ, r ≤ 0 or non-finite, or no seeds.
GSD_EXPORT FieldPtr field_opening(FieldPtr a, double r, Points seeds);
GSD_EXPORT FieldPtr field_closing(FieldPtr a, double r, Points seeds);

/// A grid's values re-distanced: the exact distance from each node to the zero set of the
/// values (marching cubes' mesh of it, gsd::contour), with each node's sign kept. Where the
/// values never change sign, ± the grid's diagonal.
GSD_EXPORT std::vector<float> redistance(const GridSpec& grid, const std::vector<float>& values);

}  // namespace gsd
