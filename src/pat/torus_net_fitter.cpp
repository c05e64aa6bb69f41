// gsd::TorusNet: loads a model once, then fits clouds on the chosen device (GPU kernels, or
// the CPU reference of torus_net.cpp).
#include "gpu/on_device.hpp"
#include <gsd/pat.hpp>
#include <gsd/spatial.hpp>

#include "pat/torus_net.hpp"
#include "pat/torus_net_gpu.hpp"

#include <future>
#include <memory>
#include <utility>

namespace gsd {

struct TorusNet::Impl {
    TorusNetOptions options;
    // The shipped model lives for the whole process; a loaded one is owned here.
    std::shared_ptr<const pat::TorusNetModel> model;
};

TorusNet::TorusNet(TorusNetOptions options) {
    auto impl = std::make_shared<Impl>();
    if (options.model.empty())
        impl->model = std::shared_ptr<const pat::TorusNetModel>(&pat::TorusNetModel::shipped(), [](auto*) {});
    else impl->model = std::make_shared<const pat::TorusNetModel>(pat::TorusNetModel::load(options.model));
    impl->options = std::move(options);
    impl_ = std::move(impl);
}

int TorusNet::k() const { return impl_->model->k; }

const TorusNetOptions& TorusNet::options() const { return impl_->options; }

std::string TorusNet::description() const {
    const pat::TorusNetModel& m = *impl_->model;
    std::string d = "TorusNet k=" + std::to_string(m.k) + ", width " + std::to_string(m.width) + ", " +
                    std::to_string(m.blocks) + " blocks, " + std::to_string(m.heads) + " heads, MLP " +
                    std::to_string(m.mlp);
    return m.description.empty() ? d : d + " (" + m.description + ")";
}

FittedTori TorusNet::fit(const PointCloud& cloud, const ProgressFn& progress) const {
    const pat::TorusNetModel& model = *impl_->model;
    const Eigen::Index n = cloud.size();
    if (cloud.normals.rows() != n) throw Error("point cloud has " + std::to_string(n) + " points but " +
                                               std::to_string(cloud.normals.rows()) + " normals");
    // The network reads exactly k tokens; a smaller neighborhood is not something it has seen.
    if (n < model.k)
        throw Error("the point cloud has " + std::to_string(n) + " points; TorusNet needs at least k = " +
                    std::to_string(model.k) + " (its neighborhood size)");
    // Measured: 316 B per point at 10⁶ (the CPU fits one neighborhood per thread at a time: the
    // cloud, its tree, the tori and the .tori written in memory grow with n); docs/io.md.
    check_memory(384.0 * double(n), "cloud", "fitting TorusNet to " + std::to_string(n) + " points");
    // The CPU's kd-tree (its neighbourhoods, on the CPU path) and the spacing, on a thread of
    // its own: a device fits meanwhile (nanoflann builds the tree on one core; at 10⁶ points
    // that and the spacing were a fifth of a fit on an H200).
    std::future<std::pair<std::unique_ptr<KdTree>, double>> tree_and_spacing = std::async(std::launch::async, [&cloud] {
        auto tree = std::make_unique<KdTree>(cloud.points);
        const double spacing = mean_spacing(*tree);
        return std::make_pair(std::move(tree), spacing);
    });
    FittedTori out;
    out.points = cloud.points;
    out.normals = cloud.normals;
    out.fitter = "net";

    // A failure on the device is an error, not a fallback: the caller asked for this device.
    const gpu::DeviceRun run = gpu::on_device(impl_->options.device, [&](const auto& ctx, std::string&) {
        pat::predict_jets_gpu(model, cloud, *ctx, out.jets, out.tangents, impl_->options.chunk_size, progress);
        return true;
    });
    const auto [tree, spacing] = tree_and_spacing.get();
    out.spacing = spacing;
    if (!run) pat::predict_jets_cpu(model, cloud, *tree, out.jets, out.tangents, progress);
    return out;
}

}  // namespace gsd
