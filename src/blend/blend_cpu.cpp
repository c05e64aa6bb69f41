// CPU reference of the blend engine, in double precision.
#include "blend/blend.hpp"

#include <algorithm>
#include <cmath>

namespace gsd::blend {

Params resolve(const BlendOptions& opt, const Source& src, bool gradient) {
    if (!(opt.C > 0 && opt.C <= 87)) throw Error("C", "C must be in (0, 87] (exp(−C) must stay a float32 normal)");
    if (opt.fallback_k < 1) throw Error("fallback_k", "the fallback neighbor count must be ≥ 1");
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
    if (points_) return points_->row(Eigen::Index(i)).transpose();
    const std::size_t nz = std::size_t(grid_.nz), nyz = std::size_t(grid_.ny) * nz;
    return grid_.node(int(i / nyz), int((i / nz) % std::size_t(grid_.ny)), int(i % nz));
}

namespace {

// Running sums of one query. With W = Σw, φ = Σ w g / W, and
// ∇φ = (Σ w ∇g − λ Σ w (g − φ) û + ∂φ/∂λ ∇λ) / W, where û = (x − p)/d.
struct Accumulator {
    double W = 0, G = 0, GD = 0, D = 0;
    Eigen::Vector3d Gg = Eigen::Vector3d::Zero(), U = Eigen::Vector3d::Zero(), GU = Eigen::Vector3d::Zero();
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

// Signed Hopf–Cole (eq. 5.8): φ = sign(w)(−log|w|/λ + σ) with the screened dipole sum w.
double shc_value(const Source& src, const std::vector<Neighbor>& set, const Eigen::Vector3d& x,
                 double lambda, double sigma) {
    const double dmin = 1e-6 * src.spacing;
    double w = 0;
    for (const Neighbor& nb : set) {
        const double d = std::max(nb.distance, dmin);
        const Eigen::Vector3d n = src.normals.row(nb.index).transpose();
        const double dot = (x - src.points.row(nb.index).transpose()).dot(n);
        w += src.areas[nb.index] * (lambda * d + 1) * dot / (2 * M_PI * d * d * d) *
             std::exp(-lambda * (d - sigma));
    }
    const double mag = std::max(std::abs(w), 1e-300);
    return (w < 0 ? -1.0 : 1.0) * (-std::log(mag) / lambda + sigma);
}

// Picks the summed set and its λ, σ (BlendOptions): returns whether λ varies with x.
bool choose_set(const KdTree& tree, const Params& p, const Eigen::Vector3d& x,
                std::vector<Neighbor>& set, double& lambda, double& sigma, std::uint32_t& far) {
    const Eigen::Index n = tree.points().rows();
    if (p.exact) {
        set.resize(std::size_t(n));
        for (Eigen::Index i = 0; i < n; ++i)
            set[std::size_t(i)] = {std::uint32_t(i), (tree.points().row(i).transpose() - x).norm()};
    } else {
        tree.radius(x, p.r_eval, set);
        if (!set.empty()) {
            sigma = 0.5 * p.r_eval;
            lambda = p.C / sigma;
            return false;
        }
        tree.knn(x, std::size_t(p.fallback_k), set);
    }
    double dmax = 0;
    far = set.front().index;
    for (const Neighbor& nb : set)
        if (nb.distance > dmax) { dmax = nb.distance; far = nb.index; }
    sigma = std::max(0.5 * dmax, 1e-300);
    lambda = p.C / sigma;
    return true;
}

}  // namespace

double evaluate_one(const Source& src, const KdTree& tree, const Params& p, const Eigen::Vector3d& x,
                    Eigen::Vector3d* grad, std::vector<Neighbor>& set) {
    double lambda = 0, sigma = 0;
    std::uint32_t far = 0;
    const bool lambda_varies = choose_set(tree, p, x, set, lambda, sigma, far);
    if (src.kind == Kind::Shc) {
        if (grad) grad->setZero();
        return shc_value(src, set, x, lambda, sigma);
    }
    Accumulator a;
    for (const Neighbor& nb : set) {
        const PointTerm t = point_term(src, nb.index, x, grad != nullptr);
        const double w = t.weight_scale * std::exp(-lambda * (nb.distance - sigma));
        a.W += w;
        a.G += w * t.g;
        if (!grad) continue;
        const Eigen::Vector3d u = nb.distance > 0 ? Eigen::Vector3d((x - src.points.row(nb.index).transpose()) / nb.distance)
                                                  : Eigen::Vector3d::Zero();
        a.Gg += w * t.grad_g;
        a.U += w * u;
        a.GU += w * t.g * u;
        a.D += w * nb.distance;
        a.GD += w * t.g * nb.distance;
    }
    const double phi = a.G / a.W;
    if (grad) {
        Eigen::Vector3d g = (a.Gg - lambda * (a.GU - phi * a.U)) / a.W;
        if (lambda_varies) {
            // λ = 2C / d_far: ∇λ = −(λ / d_far) û_far; ∂φ/∂λ = −Σ w (g − φ) d / W.
            const Eigen::Vector3d xf = x - src.points.row(far).transpose();
            const double dfar = xf.norm();
            if (dfar > 0) {
                const double dphi_dlambda = -(a.GD - phi * a.D) / a.W;
                g += dphi_dlambda * (-(lambda / dfar) * xf / dfar);
            }
        }
        *grad = g;
    }
    return phi;
}

void evaluate_cpu(const Source& src, const KdTree& tree, const Params& p, const Queries& q, Output out,
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
