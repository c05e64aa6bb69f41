// The winding walk's body, which sum_tree.cpp includes twice: as winding_lanes_generic and, in
// a region compiled for AVX2 and FMA, as winding_lanes_avx2 (GSD_WALK_FN names it,
// GSD_WALK_MASK is its lane-mask function). No include guard, on purpose.

// The packet walk. Lanes are arrays of kLanes numbers, and every per-lane loop is a `simd` loop
// of fixed length, so the compiler turns it into vector code (8 float32 lanes or 4 double
// lanes per AVX2 register; -fno-math-errno lets sqrt vectorize). An entry on the stack carries
// the node and the lanes that still need it; at a node, the lanes that accept it add its
// expansion (in Real, in the root's normalized coordinates), the rest go on to its children
// (or, at a leaf, get its elements summed exactly, in double: on every lane at once, added to
// those that need them). The walk runs from each of `starts` in turn.
template <class Real>
void SumTree::GSD_WALK_FN(const std::uint32_t* starts, std::size_t start_count, const double* x, const double* y,
                          const double* z, int n, double beta, double tolerance, double* w, std::size_t& terms) const {
    constexpr int L = kLanes;
    const WindingTestT<Real>* tests;
    const WindingNodeT<Real>* wnodes;
    if constexpr (sizeof(Real) == sizeof(float)) {
        tests = wtests_f_.data();
        wnodes = wnodes_f_.data();
    } else {
        tests = wtests_.data();
        wnodes = wnodes_.data();
    }
    alignas(64) double X[L], Y[L], Z[L], W[L];
    alignas(64) Real XR[L], YR[L], ZR[L], WR[L];
    for (int l = 0; l < L; ++l) {
        const int s = l < n ? l : 0;  // idle lanes repeat lane 0 and are masked off
        X[l] = x[s];
        Y[l] = y[s];
        Z[l] = z[s];
        W[l] = 0;
        XR[l] = Real((X[l] - w_origin_[0]) * w_scale_);
        YR[l] = Real((Y[l] - w_origin_[1]) * w_scale_);
        ZR[l] = Real((Z[l] - w_origin_[2]) * w_scale_);
        WR[l] = 0;
    }
    struct Entry {
        std::uint32_t node, lanes;
    };
    Entry stack[kStack];
    int top = 0;
    std::size_t count = 0;
    const Real reach_scale = Real(sums::winding_reach_scale(tolerance)), beta_r = Real(beta);
    // Each start's subtree in turn, depth first: with the starts in the order the walk from
    // the root would reach them, the lanes visit the same nodes in the same order.
    for (std::size_t first = 0; first < start_count; ++first) {
        stack[top++] = {starts[first], (1u << n) - 1};
        while (top > 0) {
            const Entry e = stack[--top];
            const WindingTestT<Real>& t = tests[e.node];
            const Real reach2 = sums::winding_reach2(t.rho, t.q, beta_r, reach_scale);
            alignas(64) Real dx[L], dy[L], dz[L], d2[L], term[L];
#pragma omp simd
            for (int l = 0; l < L; ++l) {
                dx[l] = XR[l] - t.c[0];
                dy[l] = YR[l] - t.c[1];
                dz[l] = ZR[l] - t.c[2];
                d2[l] = dx[l] * dx[l] + dy[l] * dy[l] + dz[l] * dz[l];
            }
            const std::uint32_t accepted = GSD_WALK_MASK(d2, reach2) & e.lanes;
            if (accepted) {  // the square roots only now, for the packet's expansion
                const WindingNodeT<Real>& nd = wnodes[e.node];
#pragma omp simd
                for (int l = 0; l < L; ++l) term[l] = winding_expansion(nd, dx[l], dy[l], dz[l], Real(1) / std::sqrt(d2[l]));
#pragma omp simd
                for (int l = 0; l < L; ++l) WR[l] += (accepted >> l & 1) ? term[l] : Real(0);
                count += std::size_t(__builtin_popcount(accepted));
            }
            const std::uint32_t rest = e.lanes & ~accepted;
            if (!rest) continue;
            if (e.node >= first_leaf_) {  // a leaf's elements exactly, every lane at once
                const Node& h = nodes_[e.node];
                alignas(64) double exact[L];
                for (std::uint32_t j = h.begin; j < h.end; ++j) {
                    const double* p = corners(j);
                    if (is_point_[j]) {
                        const double* v = vector(j);
#pragma omp simd
                        for (int l = 0; l < L; ++l) exact[l] = point_winding_lane(X[l], Y[l], Z[l], p, v);
                    } else {
#pragma omp simd
                        for (int l = 0; l < L; ++l) exact[l] = triangle_winding_lane(X[l], Y[l], Z[l], p);
                    }
#pragma omp simd
                    for (int l = 0; l < L; ++l) W[l] += (rest >> l & 1) ? exact[l] : 0.0;
                }
                count += std::size_t(__builtin_popcount(rest)) * (h.end - h.begin);
            } else {
                stack[top++] = {2 * e.node + 1, rest};
                stack[top++] = {2 * e.node + 2, rest};
            }
        }
    }
    for (int l = 0; l < n; ++l) w[l] = W[l] + double(WR[l]);
    terms += count;
}

