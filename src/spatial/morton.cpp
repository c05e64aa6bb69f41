// Morton order of query points (spatial/morton.hpp).
#include "spatial/morton.hpp"

#include "core/uninitialized.hpp"

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <string>

#include <omp.h>


namespace gsd::spatial {

bool sort_queries_for_device() {
    static const bool sort = [] {
        const char* v = std::getenv("GSD_QUERY_ORDER");
        return !(v && std::string(v) == "input");
    }();
    return sort;
}

std::vector<std::uint32_t> morton_order(PointsView q) {
    const auto n = std::size_t(q.rows());
    std::vector<std::uint32_t> order;
    if (n < 2) {
        order.assign(n, 0);
        return order;
    }
    const bool parallel = n > 65536;
    // The box, in parallel (a serial pass over 10⁷ queries took as long as the GPU's sums).
    Eigen::Vector3d lo = Eigen::Vector3d::Constant(INFINITY), hi = Eigen::Vector3d::Constant(-INFINITY);
#pragma omp parallel if (parallel)
    {
        Eigen::Vector3d l = Eigen::Vector3d::Constant(INFINITY), h = Eigen::Vector3d::Constant(-INFINITY);
#pragma omp for schedule(static) nowait
        for (Eigen::Index i = 0; i < q.rows(); ++i)
            for (int a = 0; a < 3; ++a) {
                l[a] = std::min(l[a], q(i, a));
                h[a] = std::max(h[a], q(i, a));
            }
#pragma omp critical
        {
            lo = lo.cwiseMin(l);
            hi = hi.cwiseMax(h);
        }
    }
    const Eigen::Vector3d scale = (1023.0 / (hi - lo).array().max(1e-300)).matrix();
    auto spread = [](std::uint64_t v) {  // 10 bits → every third of 30
        v = (v | (v << 16)) & 0x030000FFull;
        v = (v | (v << 8)) & 0x0300F00Full;
        v = (v | (v << 4)) & 0x030C30C3ull;
        v = (v | (v << 2)) & 0x09249249ull;
        return v;
    };
    // key << 32 | index; not zero-filled (the loops below write every entry first, in parallel:
    // the pages are touched by the threads that use them).
    detail::UninitializedVector<std::uint64_t> item(n), next(n);
#pragma omp parallel for schedule(static) if (parallel)
    for (std::size_t i = 0; i < n; ++i) {
        std::uint64_t k = 0;
        for (int a = 0; a < 3; ++a) {
            // Clamped so that a non-finite coordinate (NaN compares false) takes cell 0, not an
            // undefined conversion: it only moves the point in the order.
            double u = (q(Eigen::Index(i), a) - lo[a]) * scale[a];
            u = u >= 0 ? (u <= 1023 ? u : 1023.0) : 0.0;
            k |= spread(std::uint64_t(u)) << a;
        }
        item[i] = k << 32 | i;
    }
    // By key, stable: three counting passes of 10 bits (std::sort of 10⁶ keys took 6 % of a
    // whole `gsd winding` run), over blocks in parallel where there are many threads: a
    // histogram per block, then each block scatters from its own offsets. Measured for 10⁷ keys:
    // on a 16-core host 234 ms in all with 16 blocks, 430 ms with one; on the 2-core machine
    // one block 0.16 s, two 0.35–0.5 s (each pass streams at memory speed on one thread there).
    const int threads = omp_get_max_threads();
    const int blocks = parallel && threads >= 8 ? threads : 1;
    std::vector<std::size_t> start(std::size_t(blocks) * 1024);
    auto block_begin = [&](int b) { return n * std::size_t(b) / std::size_t(blocks); };
    for (int shift = 32; shift < 62; shift += 10) {
        std::fill(start.begin(), start.end(), 0);
#pragma omp parallel for schedule(static, 1) num_threads(blocks)
        for (int b = 0; b < blocks; ++b) {
            std::size_t* count = &start[std::size_t(b) * 1024];
            for (std::size_t i = block_begin(b); i < block_begin(b + 1); ++i) ++count[item[i] >> shift & 1023];
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
            for (std::size_t i = block_begin(b); i < block_begin(b + 1); ++i) next[at[item[i] >> shift & 1023]++] = item[i];
        }
        item.swap(next);
    }
    order.resize(n);
#pragma omp parallel for schedule(static) if (parallel)
    for (std::size_t i = 0; i < n; ++i) order[i] = std::uint32_t(item[i] & 0xffffffffu);
    return order;
}

GridBricks::GridBricks(const GridSpec& grid, int brick)
    : nx_(grid.nx), ny_(grid.ny), nz_(grid.nz), bits_(brick == 4 ? 2 : 1) {
    if (brick != 2 && brick != 4) throw Error("GridBricks", "a brick's side is 2 or 4, not " + std::to_string(brick));
    const std::size_t b = std::size_t(1) << bits_;
    bx_ = (std::size_t(nx_) + b - 1) / b;
    by_ = (std::size_t(ny_) + b - 1) / b;
    bz_ = (std::size_t(nz_) + b - 1) / b;
    per_brick_ = b * b * b;
    // Morton within a brick: bit 3l + (2 − a) of the place is bit l of the offset along axis a.
    offsets_.resize(per_brick_);
    for (std::size_t m = 0; m < per_brick_; ++m)
        for (int a = 0; a < 3; ++a) {
            std::size_t offset = 0;
            for (int l = 0; l < bits_; ++l) offset |= ((m >> (3 * l + (2 - a))) & 1u) << l;
            offsets_[m][std::size_t(a)] = std::uint8_t(offset);
        }
}

bool GridBricks::node(std::size_t item, int ijk[3], std::size_t& linear) const {
    return Cursor(*this, item).node(ijk, linear);
}

GridBricks::Cursor::Cursor(const GridBricks& bricks, std::size_t item) : b_(&bricks) {
    const std::size_t brick = item / bricks.per_brick_;
    m_ = item % bricks.per_brick_;
    brick_[0] = brick / (bricks.by_ * bricks.bz_);
    brick_[1] = (brick / bricks.bz_) % bricks.by_;
    brick_[2] = brick % bricks.bz_;
}

bool GridBricks::Cursor::node(int ijk[3], std::size_t& linear) const {
    const GridBricks& b = *b_;
    const int n[3] = {b.nx_, b.ny_, b.nz_};
    bool inside = true;
    for (int a = 0; a < 3; ++a) {
        const std::size_t v = (brick_[a] << b.bits_) + b.offsets_[m_][std::size_t(a)];
        inside = inside && v < std::size_t(n[a]);
        ijk[a] = int(std::min<std::size_t>(v, std::size_t(n[a] - 1)));
    }
    linear = (std::size_t(ijk[0]) * std::size_t(b.ny_) + std::size_t(ijk[1])) * std::size_t(b.nz_) + std::size_t(ijk[2]);
    return inside;
}

void GridBricks::Cursor::next() {
    if (++m_ < b_->per_brick_) return;
    m_ = 0;  // the next brick, in C order
    if (++brick_[2] < b_->bz_) return;
    brick_[2] = 0;
    if (++brick_[1] < b_->by_) return;
    brick_[1] = 0;
    ++brick_[0];
}

}  // namespace gsd::spatial
