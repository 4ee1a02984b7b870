// All metrics of one prediction, in the evaluation frame of reference §3.
#include <ATen/ATen.h>

#include "pumeta/core/tensor_checks.h"
#include "pumeta/metrics/metrics.h"

namespace pumeta {

MetricReport evaluate(const at::Tensor& pred, const at::Tensor& gt, const TriangleMesh* mesh) {
    check_points(pred, "prediction", 1);
    check_points(gt, "ground truth", 1);

    // GT's bounding-box centre -> 0 and its largest radius from that centre -> 1, applied to
    // everything: normalising pred on its own would hide a shifted or scaled prediction.
    at::Tensor g = gt.to(at::kCPU, at::kDouble);
    at::Tensor center = (std::get<0>(g.min(0)) + std::get<0>(g.max(0))) / 2;
    double radius = (g - center).norm(2, 1).max().item<double>();
    double scale = radius > 0 ? 1 / radius : 1.0;
    auto to_frame = [&](const at::Tensor& points) {
        return ((points.to(at::kCPU, at::kDouble) - center) * scale).to(at::kFloat);
    };
    at::Tensor pred_frame = to_frame(pred);
    at::Tensor gt_frame = to_frame(gt);

    MetricReport report;
    report.cd = chamfer_distance(pred_frame, gt_frame);
    report.hd = hausdorff_distance(pred_frame, gt_frame);
    report.hd_legacy = hausdorff_distance_legacy(pred_frame, gt_frame);
    report.psnr = psnr_d1(pred_frame, gt_frame);
    if (mesh) {
        check_points(mesh->vertices, "mesh vertices", 1);
        report.p2f = point_to_face_distance(pred_frame, {to_frame(mesh->vertices), mesh->faces});
    }
    report.n_pred = pred.size(0);
    report.n_gt = gt.size(0);
    return report;
}

}  // namespace pumeta
