// TorusNet's CPU reference (docs/torusnet.md), in double: the tokens of one neighborhood, the
// forward pass, and every point of a cloud. The GPU kernels are tested against it. Private to
// the library; the tests call it directly.
#pragma once

#include "pat/torus_net_model.hpp"

#include <gsd/pat.hpp>
#include <gsd/spatial.hpp>

#include <Eigen/Core>

#include <cstdint>
#include <vector>

namespace gsd::pat {

/// The neighborhood of point i, the way every implementation must see it: token 0 is i itself
/// (even when duplicates of it tie at distance 0), then its k − 1 nearest other points, nearest
/// first. `scratch` is reused between calls. The tree must hold at least k points.
void torusnet_neighbors(const KdTree& tree, std::uint32_t i, int k, std::vector<Neighbor>& scratch,
                        std::vector<std::uint32_t>& tokens);

/// Token features [k × 7] (row-major) and the scale m of one neighborhood: nb_points[0] is the
/// center, nb_normals[0] its normal n (normalized here), s = tangent_of(n), t = n × s.
void torusnet_features(const TorusNetModel& model, const Eigen::Vector3d* nb_points,
                       const Eigen::Vector3d* nb_normals, const Eigen::Vector3d& s, double* features,
                       double& scale);

/// The network in double: its weights converted once, then any number of forward passes
/// (thread-safe: predict() only reads).
class TorusNetCpu {
public:
    explicit TorusNetCpu(const TorusNetModel& model);
    /// The jet of one neighborhood from its k × 7 features (row-major) and scale m.
    Jet predict(const double* features, double scale) const;

    // The weights in double (public for the helpers of torus_net.cpp).
    struct Linear {
        Eigen::MatrixXd wt;     ///< weightᵀ, [in, out]: rows of tokens times wt
        Eigen::RowVectorXd b;   ///< [out]
    };
    struct Norm {
        Eigen::RowVectorXd gamma, beta;
    };
    struct Block {
        Norm norm1, norm2;
        Linear qkv, proj, fc1, fc2;
    };

private:
    int k_, heads_;  // tokens per point, attention heads (the width is in the weights' shapes)
    Linear embed_, head_;
    Norm embed_norm_, final_norm_;
    std::vector<Block> blocks_;
};

/// One forward pass (converts the weights each call: for tests; use TorusNetCpu in loops).
Jet torusnet_predict(const TorusNetModel& model, const double* features, double scale);

/// Jets and tangents (s = tangent_of(n)) of every point of a validated cloud with at least
/// model.k points; `tree` indexes cloud.points. OpenMP; progress as ("fit", fraction).
void predict_jets_cpu(const TorusNetModel& model, const PointCloud& cloud, const KdTree& tree,
                      std::vector<Jet>& jets, Points& tangents, const ProgressFn& progress);

}  // namespace gsd::pat
