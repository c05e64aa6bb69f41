// CPU reference of the blend engine, in double precision.
#include "blend/blend.hpp"

#include <algorithm>
#include <cmath>

namespace gsd::blend {

Params resolve(const BlendOptions& opt, const Source& src, bool gradient) {
    if (!(opt.C > 0 && opt.C <= 87)) throw Error("BlendOptions::C", "C must be in (0, 87] (exp(−C) must stay a float32 normal)");
    if (opt.fallback_k < 1) throw Error("BlendOptions::fallback_k", "the fallback neighbor count must be ≥ 1");
    Params p;
    p.exact = opt.exact;
    p.C = opt.C;
    p.fallback_k = int(std::min<Eigen::Index>(opt.fallback_k, src.points.rows()));
    p.gradient = gradient;
    p.r_eval = opt.r_eval > 0 ? opt.r_eval : opt.r_eval_spacings * src.spacing;
    if (!p.exact && !(p.r_eval > 0 && std::isfinite(p.r_eval)))
        throw Error("r_eval", "the evaluation radius must be > 0 (is the cloud's spacing zero?)");
    return p;
}

Eigen::Vector3d Queries::at(std::size_t i) const {
    if (points_) return {points_[i * stride_], points_[i * stride_ + 1], points_[i * stride_ + 2]};
    const std::size_t nz = std::size_t(grid_.nz), nyz = std::size_t(grid_.ny) * nz;
    return grid_.node(int(i / nyz), int((i / nz) % std::size_t(grid_.ny)), int(i % nz));
}

namespace {

// The summed set of one query and its blend parameters (BlendOptions):
//   exact:        every point; ρ = max distance; no taper
//   accelerated:  ρ = max(r_eval, d_k) with d_k the distance to the k-th nearest point; the
//                 points within ρ, weighted by the taper T(d/ρ) that vanishes at ρ
// Then σ = ρ/2 and λ = C/σ (eq. 5.7 with the set's largest distance ρ).
struct Set {
    double rho = 0, sigma = 0, lambda = 0;
    bool tapered = false;
    bool rho_varies = false;  // ρ = d_far depends on x (exact sum, or fewer than k points in r_eval)
    std::uint32_t far = 0;    // the point at distance ρ when rho_varies
};

Set choose_set(const Source& src, const spatial::BoxTree& tree, const Params& p, const Eigen::Vector3d& x,
               std::vector<Neighbor>& nb) {
    Set s;
    if (p.exact) {
        const Eigen::Index n = src.points.rows();
        nb.resize(std::size_t(n));
        for (Eigen::Index i = 0; i < n; ++i)
            nb[std::size_t(i)] = {std::uint32_t(i), (src.points.row(i).transpose() - x).norm()};
        s.rho_varies = true;
    } else {
        s.tapered = true;
        tree.radius(x, p.r_eval, nb);
        if (nb.size() >= std::size_t(p.fallback_k)) {
            s.rho = p.r_eval;
        } else {
            tree.knn(x, std::size_t(p.fallback_k), nb);
            s.rho_varies = true;
        }
    }
    if (s.rho_varies) {
        s.far = nb.front().index;
        for (const Neighbor& n : nb)
            if (n.distance > s.rho) { s.rho = n.distance; s.far = n.index; }
    }
    s.rho = std::max(s.rho, 1e-300);
    s.sigma = 0.5 * s.rho;
    s.lambda = p.C / s.sigma;
    return s;
}

// Running sums of one query, with e = exp(−λ(d − σ))·A, w = e·T(d/ρ), q = e·T'(d/ρ), û = (x − p)/d:
// W = Σw, G = Σwg, Gg = Σw∇g, U = Σwû, GU = Σwgû, D = Σwd, GD = Σwgd, QU = Σqû, QGU = Σqgû,
// QD = Σqd, QGD = Σqgd. Then φ = G/W and
// ∇φ = (Gg − λ(GU − φU) + (QGU − φQU)/ρ + ∇ρ[(λ/ρ)(GD − φD) − (QGD − φQD)/ρ²]) / W.
struct Accumulator {
    double W = 0, G = 0, D = 0, GD = 0, QD = 0, QGD = 0;
    Eigen::Vector3d Gg = Eigen::Vector3d::Zero(), U = Eigen::Vector3d::Zero(), GU = Eigen::Vector3d::Zero(),
                    QU = Eigen::Vector3d::Zero(), QGU = Eigen::Vector3d::Zero();
};

struct PointTerm {
    double g;                // per-point value
    Eigen::Vector3d grad_g;  // its gradient
    double weight_scale;     // area weight (1 for PAT)
};

PointTerm point_term(const Source& src, std::uint32_t i, const Eigen::Vector3d& x, bool gradient) {
    PointTerm t;
    if (src.kind == Kind::Pat) {
        t.g = torus_sdf(src.tori[i], x, gradient ? &t.grad_g : nullptr);
        t.weight_scale = 1;
    } else {
        const Eigen::Vector3d n = src.normals.row(i).transpose();
        t.g = (x - src.points.row(i).transpose()).dot(n);
        t.grad_g = n;
        t.weight_scale = src.areas[i];
    }
    return t;
}

// Signed Hopf–Cole (eq. 5.8): φ = sign(w)(−log|w|/λ + σ) with the screened dipole sum w. Its
// value depends on the scale of w, not only on relative weights, so it is not tapered: the
// taper would shrink w for far queries and bias φ by log(T)/λ.
double shc_value(const Source& src, const std::vector<Neighbor>& nb, const Eigen::Vector3d& x, const Set& s) {
    const double dmin = 1e-6 * src.spacing;
    double w = 0;
    for (const Neighbor& n : nb) {
        const double d = std::max(n.distance, dmin);
        const Eigen::Vector3d nrm = src.normals.row(n.index).transpose();
        const double dot = (x - src.points.row(n.index).transpose()).dot(nrm);
        w += src.areas[n.index] * (s.lambda * d + 1) * dot / (2 * M_PI * d * d * d) *
             std::exp(-s.lambda * (d - s.sigma));
    }
    const double mag = std::max(std::abs(w), 1e-300);
    return (w < 0 ? -1.0 : 1.0) * (-std::log(mag) / s.lambda + s.sigma);
}

}  // namespace

double evaluate_one(const Source& src, const spatial::BoxTree& tree, const Params& p, const Eigen::Vector3d& x,
                    Eigen::Vector3d* grad, std::vector<Neighbor>& nb) {
    const Set s = choose_set(src, tree, p, x, nb);
    if (src.kind == Kind::Shc) {
        if (grad) grad->setZero();
        return shc_value(src, nb, x, s);
    }
    Accumulator a;
    for (const Neighbor& n : nb) {
        const PointTerm t = point_term(src, n.index, x, grad != nullptr);
        const double e = t.weight_scale * std::exp(-s.lambda * (n.distance - s.sigma));
        const double v = n.distance / s.rho;
        const double w = s.tapered ? e * blend_taper(v) : e;
        a.W += w;
        a.G += w * t.g;
        if (!grad) continue;
        const Eigen::Vector3d u = n.distance > 0 ? Eigen::Vector3d((x - src.points.row(n.index).transpose()) / n.distance)
                                                 : Eigen::Vector3d::Zero();
        a.Gg += w * t.grad_g;
        a.U += w * u;
        a.GU += w * t.g * u;
        a.D += w * n.distance;
        a.GD += w * t.g * n.distance;
        if (s.tapered) {
            const double q = e * blend_taper_derivative(v);
            a.QU += q * u;
            a.QGU += q * t.g * u;
            a.QD += q * n.distance;
            a.QGD += q * t.g * n.distance;
        }
    }
    const double phi = a.G / a.W;
    if (grad) {
        Eigen::Vector3d g = a.Gg - s.lambda * (a.GU - phi * a.U) + (a.QGU - phi * a.QU) / s.rho;
        if (s.rho_varies) {
            const Eigen::Vector3d xf = x - src.points.row(s.far).transpose();
            const double dfar = xf.norm();
            if (dfar > 0) {
                const Eigen::Vector3d grad_rho = xf / dfar;
                g += grad_rho * ((s.lambda / s.rho) * (a.GD - phi * a.D) - (a.QGD - phi * a.QD) / (s.rho * s.rho));
            }
        }
        *grad = g / a.W;
    }
    return phi;
}

void evaluate_cpu(const Source& src, const spatial::BoxTree& tree, const Params& p, const Queries& q, Output out,
                  const ProgressFn& progress) {
    const std::size_t n = q.size();
    const std::size_t block = p.exact ? 4096 : 65536;
    for (std::size_t first = 0; first < n; first += block) {
        const std::size_t last = std::min(n, first + block);
#pragma omp parallel
        {
            std::vector<Neighbor> set;
#pragma omp for schedule(dynamic, 64)
            for (std::size_t i = first; i < last; ++i) {
                Eigen::Vector3d g;
                const double phi = evaluate_one(src, tree, p, q.at(i), out.gradient ? &g : nullptr, set);
                out.phi[i] = float(phi);
                if (out.gradient)
                    for (int c = 0; c < 3; ++c) out.gradient[3 * i + std::size_t(c)] = float(g[c]);
            }
        }
        if (progress) progress("evaluate", double(last) / double(n));
    }
}

}  // namespace gsd::blend
