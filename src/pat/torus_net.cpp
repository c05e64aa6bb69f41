// TorusNet's CPU reference in double (docs/torusnet.md): neighborhoods, token features, the
// transformer's forward pass, and the loop over a cloud.
#include "pat/torus_net.hpp"

#include <Eigen/Geometry>

#include <algorithm>
#include <cmath>

namespace gsd::pat {

namespace {

using Eigen::Index;
using Eigen::MatrixXd;
using Mat = Eigen::Ref<const MatrixXd>;
using Net = TorusNetCpu;

// ---- layers (rows are tokens) -------------------------------------------------------------

MatrixXd apply(const Net::Linear& l, const Mat& x) {
    MatrixXd y = x * l.wt;
    y.rowwise() += l.b;
    return y;
}

// LayerNorm over each row: biased variance, eps 1e-5 (PyTorch's nn.LayerNorm).
MatrixXd layer_norm(const Net::Norm& n, const Mat& x) {
    MatrixXd c = x.colwise() - x.rowwise().mean();
    const Eigen::ArrayXd inv_std = (c.array().square().rowwise().mean() + 1e-5).rsqrt();
    c.array().colwise() *= inv_std;
    c.array().rowwise() *= n.gamma.array();
    c.rowwise() += n.beta;
    return c;
}

MatrixXd gelu_tanh(MatrixXd x) {
    const double c = std::sqrt(2.0 / M_PI);
    return x.unaryExpr([c](double v) { return 0.5 * v * (1 + std::tanh(c * (v + 0.044715 * v * v * v))); });
}

// Multi-head attention of the query rows q [r, W] over keys/values k, v [tokens, W].
MatrixXd attention(const Mat& q, const Mat& k, const Mat& v, int heads) {
    const Index W = q.cols(), d = W / heads;
    const double inv_sqrt_d = 1.0 / std::sqrt(double(d));
    MatrixXd out(q.rows(), W);
    for (int h = 0; h < heads; ++h) {
        MatrixXd a = q.middleCols(h * d, d) * k.middleCols(h * d, d).transpose() * inv_sqrt_d;
        a = (a.colwise() - a.rowwise().maxCoeff()).array().exp();  // softmax over keys, stably
        a.array().colwise() /= a.rowwise().sum().array();
        out.middleCols(h * d, d) = a * v.middleCols(h * d, d);
    }
    return out;
}

MatrixXd mlp(const Net::Block& b, const Mat& x) { return apply(b.fc2, gelu_tanh(apply(b.fc1, layer_norm(b.norm2, x)))); }

// A block over every token.
void block_all(const Net::Block& b, MatrixXd& x, int heads) {
    const Index W = x.cols();
    const MatrixXd qkv = apply(b.qkv, layer_norm(b.norm1, x));
    x += apply(b.proj, attention(qkv.leftCols(W), qkv.middleCols(W, W), qkv.rightCols(W), heads));
    x += mlp(b, x);
}

// The last block: only token 0 leaves it, so it needs every token's keys and values but only
// token 0's query row, attention row and MLP (exact, and ~k times less work).
MatrixXd block_token0(const Net::Block& b, const MatrixXd& x, int heads) {
    const Index W = x.cols();
    const MatrixXd y = layer_norm(b.norm1, x);
    MatrixXd kv = y * b.qkv.wt.rightCols(2 * W);
    kv.rowwise() += b.qkv.b.tail(2 * W);
    MatrixXd q0 = y.topRows(1) * b.qkv.wt.leftCols(W);
    q0.rowwise() += b.qkv.b.head(W);
    MatrixXd x0 = x.topRows(1) + apply(b.proj, attention(q0, kv.leftCols(W), kv.rightCols(W), heads));
    x0 += mlp(b, x0);
    return x0;
}

// ---- weights ------------------------------------------------------------------------------

Net::Linear to_double(const TorusNetModel& m, const NetLinear& l) {
    using RowMajorF = Eigen::Matrix<float, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;
    const Eigen::Map<const RowMajorF> w(m.params.data() + l.weight, l.out, l.in);  // [out, in]
    Net::Linear out;
    out.wt = w.transpose().cast<double>();
    out.b = Eigen::Map<const Eigen::RowVectorXf>(m.params.data() + l.bias, l.out).cast<double>();
    return out;
}

Net::Norm to_double(const TorusNetModel& m, const NetNorm& n) {
    Net::Norm out;
    out.gamma = Eigen::Map<const Eigen::RowVectorXf>(m.params.data() + n.weight, n.width).cast<double>();
    out.beta = Eigen::Map<const Eigen::RowVectorXf>(m.params.data() + n.bias, n.width).cast<double>();
    return out;
}

}  // namespace

// ---- the network --------------------------------------------------------------------------

TorusNetCpu::TorusNetCpu(const TorusNetModel& m) : k_(m.k), heads_(m.heads) {
    embed_ = to_double(m, m.embed);
    embed_norm_ = to_double(m, m.embed_norm);
    for (const NetBlock& b : m.block)
        blocks_.push_back({to_double(m, b.norm1), to_double(m, b.norm2), to_double(m, b.qkv), to_double(m, b.proj),
                           to_double(m, b.fc1), to_double(m, b.fc2)});
    final_norm_ = to_double(m, m.final_norm);
    head_ = to_double(m, m.head);
}

Jet TorusNetCpu::predict(const double* features, double m) const {
    using RowMajorD = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;
    const MatrixXd f = Eigen::Map<const RowMajorD>(features, k_, kTorusNetInputs);
    MatrixXd x = layer_norm(embed_norm_, apply(embed_, f));
    for (std::size_t b = 0; b + 1 < blocks_.size(); ++b) block_all(blocks_[b], x, heads_);
    const MatrixXd x0 = blocks_.empty() ? MatrixXd(x.topRows(1)) : block_token0(blocks_.back(), x, heads_);
    const MatrixXd r = apply(head_, layer_norm(final_norm_, x0));
    // The network works in units of m; coefficient a_ij has units of length^(1 − i − j).
    return Jet{r(0) * m, r(1), r(2), r(3) / m, r(4) / m, r(5) / m};
}

Jet torusnet_predict(const TorusNetModel& model, const double* features, double scale) {
    return TorusNetCpu(model).predict(features, scale);
}

// ---- inputs -------------------------------------------------------------------------------

void torusnet_neighbors(const KdTree& tree, std::uint32_t i, int k, std::vector<Neighbor>& scratch,
                        std::vector<std::uint32_t>& tokens) {
    tree.knn(tree.points().row(i).transpose(), std::size_t(k), scratch);
    // Among duplicates of p the search may return i anywhere, or (with k or more of them) not
    // at all: put i first and take the others in order, skipping i.
    tokens.clear();
    tokens.push_back(i);
    for (const Neighbor& nb : scratch) {
        if (tokens.size() == std::size_t(k)) break;
        if (nb.index != i) tokens.push_back(nb.index);
    }
    // The search returns fewer than k only if distances overflow, which validated clouds
    // (coordinates within ±kMaxCoordinate) rule out; never read past what came back: pad with p.
    while (tokens.size() < std::size_t(k)) tokens.push_back(i);
}

void torusnet_features(const TorusNetModel& model, const Eigen::Vector3d* nb_points,
                       const Eigen::Vector3d* nb_normals, const Eigen::Vector3d& s, double* features,
                       double& scale) {
    const int k = model.k;
    const Eigen::Vector3d& p = nb_points[0];
    const Eigen::Vector3d n = nb_normals[0] / nb_normals[0].norm();
    const Eigen::Vector3d t = n.cross(s);

    // m: the lower median of the other tokens' distances, floored at 1e-3 of the largest so
    // that a neighborhood of mostly duplicates still has a usable unit; 1 if all coincide.
    std::vector<double> dist(std::size_t(k - 1));
    for (int j = 1; j < k; ++j) dist[std::size_t(j - 1)] = (nb_points[j] - p).norm();
    const auto mid = dist.begin() + (k - 2) / 2;
    std::nth_element(dist.begin(), mid, dist.end());
    const double d_max = *std::max_element(dist.begin(), dist.end());
    double m = *mid;
    if (m <= 1e-3 * d_max) m = 1e-3 * d_max;
    if (d_max == 0) m = 1;
    scale = m;

    for (int j = 0; j < k; ++j) {
        const Eigen::Vector3d d = nb_points[j] - p;
        const Eigen::Vector3d nj = nb_normals[j] / std::max(nb_normals[j].norm(), 1e-30);
        double* f = features + std::size_t(j) * kTorusNetInputs;
        f[0] = d.dot(s) / m;
        f[1] = d.dot(t) / m;
        f[2] = d.dot(n) / m;
        f[3] = nj.dot(s);
        f[4] = nj.dot(t);
        f[5] = nj.dot(n);
        f[6] = j == 0 ? 1 : 0;
    }
}

// ---- a whole cloud ------------------------------------------------------------------------

void predict_jets_cpu(const TorusNetModel& model, const PointCloud& cloud, const KdTree& tree,
                      std::vector<Jet>& jets, Points& tangents, const ProgressFn& progress) {
    const Index n = cloud.size();
    const int k = model.k;
    if (n < k) throw Error("TorusNet needs at least k = " + std::to_string(k) + " points; the cloud has " + std::to_string(n));
    const TorusNetCpu net(model);
    jets.assign(std::size_t(n), Jet{});
    tangents.resize(n, 3);

    // Blocks keep progress reports on the calling thread, a few hundred at most.
    const Index block = std::max<Index>(1024, n / 256);
    for (Index first = 0; first < n; first += block) {
        const Index last = std::min(n, first + block);
#pragma omp parallel
        {
            std::vector<Neighbor> scratch;
            std::vector<std::uint32_t> tokens;
            const std::size_t tokens_k = std::size_t(k);
            std::vector<Eigen::Vector3d> P(tokens_k), N(tokens_k);
            std::vector<double> f(tokens_k * kTorusNetInputs);
#pragma omp for schedule(dynamic, 16)
            for (Index i = first; i < last; ++i) {
                torusnet_neighbors(tree, std::uint32_t(i), k, scratch, tokens);
                for (int j = 0; j < k; ++j) {
                    P[std::size_t(j)] = cloud.points.row(tokens[std::size_t(j)]).transpose();
                    N[std::size_t(j)] = cloud.normals.row(tokens[std::size_t(j)]).transpose();
                }
                const Eigen::Vector3d s = tangent_of(N[0].normalized());
                tangents.row(i) = s.transpose();
                double m = 1;
                torusnet_features(model, P.data(), N.data(), s, f.data(), m);
                jets[std::size_t(i)] = net.predict(f.data(), m);
            }
        }
        if (progress) progress("fit", double(last) / double(n));
    }
}

}  // namespace gsd::pat
