// Private to the library: PAT's outlier scores from tori already built, so TorusField, which
// needs the tori for its blend anyway, builds them once.
#pragma once

#include <gsd/pat.hpp>

#include <vector>

namespace gsd::pat {

/// point_confidence(fitted, options) with `tori` = fitted.tori().
PointConfidence score_points(const FittedTori& fitted, const std::vector<Torus>& tori, const OutlierOptions& options);

}  // namespace gsd::pat
