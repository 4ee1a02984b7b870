// All metrics of one prediction, in the GT frame of README.md, "Metric conventions".
#include <ATen/ATen.h>

#include "pumeta/core/tensor_checks.h"
#include "pumeta/geometry/normalize.h"
#include "pumeta/metrics/metrics.h"

namespace pumeta {

MetricReport evaluate(const at::Tensor& pred, const at::Tensor& gt, const TriangleMesh* mesh) {
    check_points(pred, "prediction", 1);
    check_points(gt, "ground truth", 1);

    // GT's bounding-box centre -> 0 and its largest radius from that centre -> 1, applied to
    // everything: normalising pred on its own would hide a shifted or scaled prediction.
    Normalization frame = unit_sphere_normalization(gt, CenterMode::kBoundingBox);
    at::Tensor pred_frame = frame.apply(pred);
    at::Tensor gt_frame = frame.apply(gt);

    MetricReport report;
    report.cd = chamfer_distance(pred_frame, gt_frame);
    report.hd = hausdorff_distance(pred_frame, gt_frame);
    report.hd_legacy = hausdorff_distance_legacy(pred_frame, gt_frame);
    report.psnr = psnr_d1(pred_frame, gt_frame);
    if (mesh) {
        check_points(mesh->vertices, "mesh vertices", 1);
        report.p2f = point_to_face_distance(pred_frame, {frame.apply(mesh->vertices), mesh->faces});
    }
    report.n_pred = pred.size(0);
    report.n_gt = gt.size(0);
    return report;
}

}  // namespace pumeta
