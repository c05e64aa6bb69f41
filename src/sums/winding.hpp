// winding.hpp — fast winding numbers over a sum tree the caller already built (what
// fast_winding_numbers does after building one): for work that needs the tree for more than the
// winding numbers (the signed distance's nearest-triangle search). Private to the library.
#pragma once

#include <gsd/sums.hpp>

namespace gsd::sums {

class SumTree;

/// fast_winding_numbers over `tree`: the same checks, device choice and results.
WindingResult winding_numbers(const SumTree& tree, PointsView queries, const WindingOptions& options,
                              const ProgressFn& progress = {});
/// The same without checking the options (callers that did).
WindingResult winding_on_tree(const SumTree& tree, PointsView queries, const WindingOptions& options,
                              const ProgressFn& progress);

}  // namespace gsd::sums
