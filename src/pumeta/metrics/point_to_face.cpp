// Point-to-face distance (P2F): how far predicted points lie from the true surface.
#include <ATen/ATen.h>

#include "pumeta/core/tensor_checks.h"
#include "pumeta/metrics/metrics.h"
#include "pumeta/metrics/triangle_bvh.h"

namespace pumeta {

double point_to_face_distance(const at::Tensor& pred, const TriangleMesh& mesh) {
    check_points(pred, "prediction", 1);
    return TriangleBvh(mesh).distances(pred).mean().item<double>();
}

}  // namespace pumeta
