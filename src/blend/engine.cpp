// Engine: picks the device for each evaluation and keeps the per-path search structures.
#include "blend/blend.hpp"

#include "gpu/on_device.hpp"

namespace gsd::blend {

Engine::Engine(Source src, BlendOptions opt) : src_(std::move(src)), opt_(std::move(opt)) {
    if (src_.points.rows() < 2) throw Error("a blended field needs at least 2 points");
    resolve(opt_, src_, false);  // reject bad options now, not at the first query
}

Engine::~Engine() = default;

const spatial::BoxTree& Engine::tree() const {
    std::lock_guard<std::mutex> lock(init_mutex_);
    if (!tree_) tree_ = std::make_unique<spatial::BoxTree>(src_.points);
    return *tree_;
}

FieldValues Engine::evaluate(const Queries& q, bool gradient, const ProgressFn& progress) const {
    const Params params = resolve(opt_, src_, gradient);
    FieldValues out;
    out.phi.resize(q.size());
    if (gradient) out.gradient.resize(3 * q.size());
    const Output dst{out.phi.data(), gradient ? out.gradient.data() : nullptr};

    // The device-side field is made on the first evaluation (its refusal, if any, said once).
    std::string field_device;
    const gpu::DeviceRun run = gpu::on_device(opt_.device, [&](const auto& ctx, std::string& why_not) {
        std::shared_ptr<GpuField> field;
        const spatial::BoxTree& search_tree = tree();  // outside the lock below: tree() takes it
        {
            std::lock_guard<std::mutex> lock(init_mutex_);
            if (!gpu_tried_) {
                gpu_tried_ = true;
                for (const auto& f : placed_)  // on_device() may have placed it there already
                    if (gpu_field_context(*f) == ctx.get()) gpu_ = f;
                if (!gpu_) gpu_ = make_gpu_field(ctx, src_, search_tree, params, why_not);
            }
            field = gpu_;
        }
        if (!field) return false;
        evaluate_gpu(*field, params, q, dst, opt_.chunk_size, progress);
        field_device = gpu_field_device(*field);  // the context it was placed on, maybe not the chosen one
        return true;
    });
    if (run) {
        out.device = field_device;
        return out;
    }
    evaluate_cpu(src_, tree(), params, q, dst, progress);
    out.device = "cpu";
    return out;
}

std::shared_ptr<GpuField> Engine::on_device(const std::shared_ptr<gpu::Context>& ctx) const {
    if (!ctx) throw Error("device", "no device context given");
    if constexpr (!gpu::kBuiltWithVulkan) throw Error("device", "gsd was built without Vulkan");
    else {
        const spatial::BoxTree& search_tree = tree();  // outside the lock below: tree() takes it
        std::lock_guard<std::mutex> lock(init_mutex_);
        if (gpu_ && gpu_field_context(*gpu_) == ctx.get()) return gpu_;  // evaluate() placed it there already
        for (const auto& f : placed_)
            if (gpu_field_context(*f) == ctx.get()) return f;
        std::string why_not;
        auto f = make_gpu_field(ctx, src_, search_tree, resolve(opt_, src_, false), why_not);
        if (!f) {
            // make_gpu_field words its reason for a fallback; here there is none to take.
            if (const auto cut = why_not.find("; using the CPU path"); cut != std::string::npos) why_not.erase(cut);
            throw Error("device", "cannot evaluate on " + gpu::device_name(*ctx) + ": " + why_not);
        }
        placed_.push_back(f);
        return f;
    }
}

}  // namespace gsd::blend

#if !defined(GSD_HAVE_VULKAN)
namespace gsd::blend {
// A build without Vulkan has no context to run on (blend_gpu.cpp is not built).
void EngineProgram::evaluate_into(const std::shared_ptr<gpu::Context>&, const gpu::DeviceQueries&,
                                  const gpu::SubmitSync&) const {
    throw Error("device", "gsd was built without Vulkan");
}
}  // namespace gsd::blend
#endif
