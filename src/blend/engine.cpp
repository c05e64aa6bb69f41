// Engine: picks the device for each evaluation and keeps the per-path search structures.
#include "blend/blend.hpp"

#include <gsd/gpu.hpp>

namespace gsd::blend {

#ifndef GSD_HAVE_VULKAN
// Without Vulkan there is no device-side field; these are never reached (select() never
// returns a context) but keep the engine's code path the same.
class GpuField {};
std::shared_ptr<GpuField> make_gpu_field(const std::shared_ptr<gpu::Context>&, const Source&,
                                         const detail::BoxTree&, const Params&, std::string& why_not) {
    why_not = "built without Vulkan";
    return nullptr;
}
void evaluate_gpu(GpuField&, const Params&, const Queries&, Output, std::size_t, const ProgressFn&) {}
std::string gpu_field_device(const GpuField&) { return "cpu"; }
const gpu::Context* gpu_field_context(const GpuField&) { return nullptr; }
#endif

Engine::Engine(Source src, BlendOptions opt) : src_(std::move(src)), opt_(std::move(opt)) {
    if (src_.points.rows() < 2) throw Error("a blended field needs at least 2 points");
    resolve(opt_, src_, false);  // reject bad options now, not at the first query
}

Engine::~Engine() = default;

const detail::BoxTree& Engine::tree() const {
    std::lock_guard<std::mutex> lock(init_mutex_);
    if (!tree_) tree_ = std::make_unique<detail::BoxTree>(src_.points);
    return *tree_;
}

FieldValues Engine::evaluate(const Queries& q, bool gradient, const ProgressFn& progress) const {
    const Params params = resolve(opt_, src_, gradient);
    FieldValues out;
    out.phi.resize(q.size());
    if (gradient) out.gradient.resize(3 * q.size());
    const Output dst{out.phi.data(), gradient ? out.gradient.data() : nullptr};

    const gpu::Selection sel = gpu::select(opt_.device);
    if (!sel.note.empty()) log_once(sel.note);
    if (sel.context) {
        std::shared_ptr<GpuField> field;
        const detail::BoxTree& search_tree = tree();  // outside the lock below: tree() takes it
        {
            std::lock_guard<std::mutex> lock(init_mutex_);
            if (!gpu_tried_) {
                gpu_tried_ = true;
                for (const auto& f : placed_)  // on_device() may have placed it there already
                    if (gpu_field_context(*f) == sel.context.get()) gpu_ = f;
                std::string why_not;
                if (!gpu_) gpu_ = make_gpu_field(sel.context, src_, search_tree, params, why_not);
                if (!gpu_) log_once(why_not);
            }
            field = gpu_;
        }
        if (field) {
            evaluate_gpu(*field, params, q, dst, opt_.chunk_size, progress);
            out.device = gpu_field_device(*field);
            return out;
        }
    }
    evaluate_cpu(src_, tree(), params, q, dst, progress);
    out.device = "cpu";
    return out;
}

std::shared_ptr<GpuField> Engine::on_device(const std::shared_ptr<gpu::Context>& ctx) const {
    if (!ctx) throw Error("device", "no device context given");
    const detail::BoxTree& search_tree = tree();  // outside the lock below: tree() takes it
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

}  // namespace gsd::blend
