#include "gpu/device_tree.hpp"

#include <cmath>

namespace gsd::gpu {

std::vector<DeviceNode> device_nodes(const spatial::BoxTree& tree) {
    std::vector<DeviceNode> out(tree.nodes().size());
    for (std::size_t i = 0; i < out.size(); ++i) {
        const spatial::BoxTree::Node& n = tree.nodes()[i];
        for (int a = 0; a < 3; ++a) {
            const float lo = float(n.lo[a]), hi = float(n.hi[a]);
            out[i].lo[a] = double(lo) > n.lo[a] ? std::nextafter(lo, -INFINITY) : lo;
            out[i].hi[a] = double(hi) < n.hi[a] ? std::nextafter(hi, INFINITY) : hi;
        }
        out[i].begin = n.begin;
        out[i].end = n.end;
    }
    return out;
}

}  // namespace gsd::gpu
