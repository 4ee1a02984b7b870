#include "pumeta/pumeta.h"

#include <ATen/ATen.h>

#include <cmath>
#include <cstring>

#include "pumeta/core/tensor_checks.h"
#include "pumeta/geometry/io.h"
#include "pumeta/inference/model_file.h"
#include "pumeta/inference/upsample.h"

namespace pumeta {

namespace {

/// InputError naming `what` when a coordinate of `points` (float32 [N,3]) is NaN or infinite:
/// the pipeline and the metrics would silently return NaN.
void check_finite(const at::Tensor& points, const std::string& what) {
    const at::Tensor bad = at::isfinite(points).all(1).logical_not();
    const int64_t count = bad.sum().item<int64_t>();
    if (count == 0) return;
    const int64_t first = bad.nonzero()[0][0].item<int64_t>();
    throw_input_error(what, "{} of {} points have NaN or infinite coordinates (the first: row {})",
                      count, points.size(0), first);
}

void check_ratio(int64_t ratio) {
    if (ratio < 0 || ratio > kMaxUpsampleRatio)
        throw_input_error("ratio", "expected 0 (the model's) to {}, found {}", kMaxUpsampleRatio,
                          ratio);
}

}  // namespace

Model::Model(const std::string& path, int64_t ratio) {
    check_ratio(ratio);
    path_ = path.empty() ? default_model_for_ratio(ratio) : path;
    served_ = std::make_unique<ServedModel>(serve(path_, ratio));
}

Model::~Model() = default;
Model::Model(Model&&) noexcept = default;
Model& Model::operator=(Model&&) noexcept = default;

int64_t Model::ratio() const { return served_->ratio; }

std::string Model::backbone() const { return served_->model.backbone->name(); }

bool Model::meta_trained() const { return served_->model.meta_trained; }

at::Tensor upsample(const Model& model, const at::Tensor& points,
                    const UpsampleSettings& settings) {
    check_points(points, "upsample input", 1);
    check_finite(points, "upsample input");
    check_ratio(settings.ratio);
    if (settings.tta_steps && (*settings.tta_steps < 0 || *settings.tta_steps > 100000))
        throw_input_error("tta_steps", "expected 0 to 100000, found {}", *settings.tta_steps);
    if (settings.tta_lr && !(*settings.tta_lr > 0 && std::isfinite(*settings.tta_lr)))
        throw_input_error("tta_lr", "expected a finite step size above 0, found {}",
                          *settings.tta_lr);
    // The same overrides and defaults as `pumeta upsample` (cli/model_args.cpp).
    const ServedModel& served = model.served();
    AdaptationOverrides overrides;
    overrides.steps = settings.tta_steps;
    overrides.step_size = settings.tta_lr;
    UpsampleOptions options;
    options.ratio = settings.ratio == 0 ? served.ratio : settings.ratio;
    options.seed = settings.seed;
    options.adaptation =
        adaptation_for(served.model.adaptation, served.model.meta_trained, overrides);
    return upsample_cloud(*served.model.backbone, points, options).points;
}

Points upsample(const Model& model, const Points& points, const UpsampleSettings& settings) {
    return to_points(upsample(model, to_tensor(points), settings));
}

at::Tensor read_points(const std::string& path) { return read_point_cloud(path).points; }

void write_points(const std::string& path, const at::Tensor& points) {
    check_points(points, path);
    check_finite(points, path);
    write_point_cloud(path, {points});
}

MetricReport metrics(const at::Tensor& pred, const at::Tensor& gt, const std::string& mesh_path) {
    check_points(pred, "prediction", 1);
    check_finite(pred, "prediction");
    check_points(gt, "ground truth", 1);
    check_finite(gt, "ground truth");
    if (mesh_path.empty()) return evaluate(pred, gt);
    const TriangleMesh mesh = read_mesh(mesh_path);
    return evaluate(pred, gt, &mesh);
}

at::Tensor to_tensor(const Points& points) {
    static_assert(sizeof(Points::value_type) == 3 * sizeof(float), "packed {x, y, z}");
    at::Tensor tensor = at::empty({static_cast<int64_t>(points.size()), 3}, at::kFloat);
    if (!points.empty())
        std::memcpy(tensor.data_ptr<float>(), points.data(), points.size() * 3 * sizeof(float));
    return tensor;
}

Points to_points(const at::Tensor& points) {
    if (!points.defined() || points.dim() != 2 || points.size(1) != 3 ||
        !at::isFloatingType(points.scalar_type()))
        throw_input_error("points", "expected floating-point points of shape [N,3], found {}",
                          shape_string(points));
    const at::Tensor values = points.to(at::kCPU, at::kFloat).contiguous();
    Points out(static_cast<size_t>(values.size(0)));
    if (!out.empty())
        std::memcpy(out.data(), values.data_ptr<float>(), out.size() * 3 * sizeof(float));
    return out;
}

}  // namespace pumeta
