// Scalar torus math shared by the CPU reference (double) and tests (float), mirrored line for
// line by shaders/torus.glsl. Everything is in a point's local frame; see docs/pat.md.
#pragma once

#include <algorithm>
#include <cmath>

namespace gsd::pat {

/// The torus of a height function, in the frame (s, t, n) of its point.
template <class T>
struct TorusFrame {
    T a00;     ///< shift along n: q = p + a00·n
    T n[3];    ///< unit normal at q
    T e1[3];   ///< unit principal direction of k1 (the torus axis)
    T k1, k2;  ///< signed principal curvatures, |k1| ≥ |k2|
};

/// Coefficients a = (a00, a10, a01, a11, a20, a02) of Q(s,t) → torus. The principal curvatures
/// solve II v = κ I v with I = [[1+a10², a10·a01], [a10·a01, 1+a01²]] and
/// II = [[2a20, a11], [a11, 2a02]] / A, A = √(1 + a10² + a01²). With I = L Lᵀ (Cholesky) this is
/// the symmetric problem C v' = κ v', C = L⁻¹ II L⁻ᵀ, v = L⁻ᵀ v', whose eigenvalue gap
/// √(((C11 − C22)/2)² + C12²) is a sum of squares: no cancellation near umbilics in float32.
template <class T>
TorusFrame<T> torus_from_jet(const T (&a)[6]) {
    const T a10 = a[1], a01 = a[2], a11 = a[3], a20 = a[4], a02 = a[5];
    const T A = std::sqrt(T(1) + a10 * a10 + a01 * a01);
    const T I11 = T(1) + a10 * a10, I12 = a10 * a01;
    const T B11 = T(2) * a20 / A, B12 = a11 / A, B22 = T(2) * a02 / A;
    // L⁻¹ = [[la, 0], [lb, ld]] for I = L Lᵀ: l11 = √I11, l21 = I12/l11, l22 = A/l11.
    const T l11 = std::sqrt(I11);
    const T la = T(1) / l11, lb = -I12 / (l11 * A), ld = l11 / A;
    const T C11 = la * la * B11;
    const T C12 = la * (lb * B11 + ld * B12);
    const T C22 = lb * lb * B11 + T(2) * lb * ld * B12 + ld * ld * B22;
    const T mean = (C11 + C22) / T(2), half = (C11 - C22) / T(2);
    const T gap = std::sqrt(half * half + C12 * C12);
    const T big = mean >= T(0) ? mean + gap : mean - gap;
    const T small = mean >= T(0) ? mean - gap : mean + gap;

    TorusFrame<T> f{};
    f.a00 = a[0];
    f.k1 = big;
    f.k2 = small;
    // Eigenvector of C for `big`: the larger of two equivalent forms; any vector at an umbilic.
    T w0 = C12, w1 = big - C11;
    const T u0 = big - C22, u1 = C12;
    if (u0 * u0 + u1 * u1 > w0 * w0 + w1 * w1) { w0 = u0; w1 = u1; }
    if (w0 * w0 + w1 * w1 <= T(1e-30)) { w0 = T(1); w1 = T(0); }
    const T v0 = la * w0 + lb * w1, v1 = ld * w1;  // v = L⁻ᵀ w
    // Tangent vector v0·X_s + v1·X_t with X_s = (1, 0, a10), X_t = (0, 1, a01).
    T e[3] = {v0, v1, v0 * a10 + v1 * a01};
    const T len = std::sqrt(e[0] * e[0] + e[1] * e[1] + e[2] * e[2]);
    for (int i = 0; i < 3; ++i) f.e1[i] = e[i] / len;
    f.n[0] = -a10 / A;
    f.n[1] = -a01 / A;
    f.n[2] = T(1) / A;
    return f;
}

/// Signed distance of the torus with curvatures (k1 along e1, k2 along e2) at the local
/// point y = (y1, y2, y3) in the frame (e1, e2, n) centered on the torus point q; optionally
/// the gradient in that frame. g > 0 on the side n points to.
template <class T>
T torus_sdf_local(T k1, T k2, T y1, T y2, T y3, T* grad) {
    const T yp2 = y2 * y2 + y3 * y3;
    const T tau = k1 != T(0) ? std::clamp(k2 / k1, T(-1), T(1)) : T(0);
    const T u2 = k2 * y2, u3 = k2 * y3 - T(1);
    const T sqrtS = std::sqrt(u2 * u2 + u3 * u3);  // |k2|·distance to the torus axis
    const T D = sqrtS + (T(1) - tau);
    // E = |k1|·(distance to the axis − R) up to sign; F = (1 − E)/k1 without cancellation.
    T E, F;
    if (D > T(1e-30)) {
        E = (k1 * k2 * yp2 - T(2) * k1 * y3 + T(2) - tau) / D;
        F = ((tau * k2 * yp2 - T(2) * tau * y3) / (sqrtS + T(1)) - k2 * yp2 + T(2) * y3) / D;
    } else {  // on the axis of a sphere: its center
        E = T(0);
        F = T(1) / k1;
    }
    const T k1y1 = k1 * y1;
    const T Q = std::sqrt(E * E + k1y1 * k1y1);  // |k1|·distance to the tube's center circle
    const T g = (F * (T(1) + E) - k1 * y1 * y1) / (T(1) + Q);
    if (grad) {
        if (Q > T(1e-30)) {
            const T w = sqrtS > T(1e-30) ? E / sqrtS : T(0);
            grad[0] = -k1y1 / Q;
            grad[1] = -w * u2 / Q;
            grad[2] = -w * u3 / Q;
        } else {  // on the tube's center circle: every direction is steepest; take n
            grad[0] = T(0);
            grad[1] = T(0);
            grad[2] = T(1);
        }
    }
    return g;
}

}  // namespace gsd::pat
