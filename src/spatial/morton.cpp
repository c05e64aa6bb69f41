// Morton order of query points (spatial/morton.hpp).
#include "spatial/morton.hpp"

#include <algorithm>
#include <cstdlib>
#include <string>

#include <omp.h>

namespace gsd::detail {

bool sort_queries_for_device() {
    static const bool sort = [] {
        const char* v = std::getenv("GSD_QUERY_ORDER");
        return !(v && std::string(v) == "input");
    }();
    return sort;
}

std::vector<std::uint32_t> morton_order(PointsView q) {
    const auto n = std::size_t(q.rows());
    std::vector<std::uint32_t> order(n);
    for (std::size_t i = 0; i < n; ++i) order[i] = std::uint32_t(i);
    if (n < 2) return order;
    const Box b = bounding_box(q);
    const Eigen::Vector3d scale = (1023.0 / b.extent().array().max(1e-300)).matrix();
    auto spread = [](std::uint64_t v) {  // 10 bits → every third of 30
        v = (v | (v << 16)) & 0x030000FFull;
        v = (v | (v << 8)) & 0x0300F00Full;
        v = (v | (v << 4)) & 0x030C30C3ull;
        v = (v | (v << 2)) & 0x09249249ull;
        return v;
    };
    std::vector<std::uint64_t> item(n), next(n);  // key << 32 | index
#pragma omp parallel for schedule(static) if (n > 65536)
    for (std::size_t i = 0; i < n; ++i) {
        std::uint64_t k = 0;
        for (int a = 0; a < 3; ++a) {
            const double u = std::clamp((q(Eigen::Index(i), a) - b.lo[a]) * scale[a], 0.0, 1023.0);
            k |= spread(std::uint64_t(u)) << a;
        }
        item[i] = k << 32 | i;
    }
    // By key, stable: three counting passes of 10 bits (std::sort of 10⁶ keys took 6 % of a
    // whole `gsd winding` run). Each pass in parallel over blocks: a histogram per block, then
    // each block scatters from its own offsets (the GPU paths sort 10⁷ queries per call, where
    // one thread's passes took longer than the kernels).
    const int blocks = n > 262144 ? std::max(1, omp_get_max_threads()) : 1;
    std::vector<std::size_t> start(std::size_t(blocks) * 1024);
    for (int shift = 32; shift < 62; shift += 10) {
        std::fill(start.begin(), start.end(), 0);
#pragma omp parallel for schedule(static, 1) num_threads(blocks)
        for (int b = 0; b < blocks; ++b) {
            std::size_t* count = &start[std::size_t(b) * 1024];
            for (std::size_t i = n * std::size_t(b) / std::size_t(blocks); i < n * std::size_t(b + 1) / std::size_t(blocks); ++i)
                ++count[item[i] >> shift & 1023];
        }
        std::size_t total = 0;  // offsets: digit-major, block-minor (keeps the sort stable)
        for (std::size_t d = 0; d < 1024; ++d)
            for (int b = 0; b < blocks; ++b) {
                std::size_t& c = start[std::size_t(b) * 1024 + d];
                const std::size_t here = c;
                c = total;
                total += here;
            }
#pragma omp parallel for schedule(static, 1) num_threads(blocks)
        for (int b = 0; b < blocks; ++b) {
            std::size_t* at = &start[std::size_t(b) * 1024];
            for (std::size_t i = n * std::size_t(b) / std::size_t(blocks); i < n * std::size_t(b + 1) / std::size_t(blocks); ++i)
                next[at[item[i] >> shift & 1023]++] = item[i];
        }
        item.swap(next);
    }
#pragma omp parallel for schedule(static) if (n > 65536)
    for (std::size_t i = 0; i < n; ++i) order[i] = std::uint32_t(item[i] & 0xffffffffu);
    return order;
}

}  // namespace gsd::detail
