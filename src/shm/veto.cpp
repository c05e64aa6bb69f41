// The outside veto (shm/veto.hpp).
#include "shm/veto.hpp"

#include "sums/sum_tree.hpp"

#include <algorithm>

namespace gsd::shm {

std::size_t veto_outside(const ShmSource& source, const VetoParams& params, std::vector<double>& phi,
                         const std::function<Eigen::Vector3d(std::size_t)>& position) {
    const Box extent_box = bounding_box(source.elements.corners);
    const double margin = params.margin * extent_box.extent().maxCoeff();
    if (!(margin > 0)) return 0;  // every element at one point: no hole to complete
    // The ramps' widths: half the margin in distance, so that a node closer than 0.75
    // margins to an element is never touched, however low its winding number (nor, so,
    // any part thinner than 1.5 margins); 0.1 in winding number.
    const double distance_band = 0.5 * margin, winding_band = 0.1;
    const sums::SumTree tree(source.elements);
    const WindingOptions criterion;  // the default accuracy: far below the band
    const std::ptrdiff_t count = std::ptrdiff_t(phi.size());
    std::size_t turned = 0;
#pragma omp parallel reduction(+ : turned)
    {
        std::uint32_t nearest = std::uint32_t(-1);  // the last node's nearest element: a good start
#pragma omp for schedule(dynamic, 4096)
        for (std::ptrdiff_t i = 0; i < count; ++i) {
            double& value = phi[std::size_t(i)];
            if (!(value < 0)) continue;
            const Eigen::Vector3d x = position(std::size_t(i));
            const double threshold = params.slope * -value + margin;
            auto far_ramp = [&](double d) { return std::clamp(0.5 + (d - threshold) / distance_band, 0.0, 1.0); };
            // Most nodes are near an element for their |φ|, and the last node's nearest
            // element says so without a search: its distance bounds the nearest one from
            // above and the ramp is monotone, so the node would stay as it is.
            if (nearest < tree.size() && far_ramp(tree.element_distance(x, nearest)) <= 0) continue;
            // Exact up to where the ramp ends; that bound prunes the search.
            const double far = far_ramp(tree.nearest_distance(x, threshold + 0.5 * distance_band, &nearest));
            if (far <= 0) continue;
            std::size_t terms = 0;
            const double w = tree.winding(x, criterion.beta, criterion.tolerance, terms);
            const double kappa = std::min(far, std::clamp(0.5 + (params.winding - w) / winding_band, 0.0, 1.0));
            value *= 1 - 2 * kappa;
            turned += kappa > 0.5;
        }
    }
    return turned;
}

}  // namespace gsd::shm
