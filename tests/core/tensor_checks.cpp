#include "pumeta/core/tensor_checks.h"

#include <ATen/ATen.h>
#include <gtest/gtest.h>

#include "pumeta/core/error.h"

namespace pumeta {

TEST(TensorChecks, AcceptsPointsAndRejectsWrongShapesWithContext) {
    EXPECT_NO_THROW(check_points(at::zeros({5, 3}), "cloud.ply", 5));
    try {
        check_points(at::zeros({5, 2}), "cloud.ply");
        FAIL() << "expected InputError";
    } catch (const InputError& e) {
        EXPECT_NE(std::string(e.what()).find("cloud.ply: expected points of shape [N,3]"),
                  std::string::npos)
            << e.what();
    }
    EXPECT_THROW(check_points(at::zeros({5, 3}, at::kDouble), "x"), InputError);
    EXPECT_THROW(check_points(at::zeros({4, 3}), "x", 5), InputError);
}

TEST(TensorChecks, FacesOutOfRangeAreRejected) {
    at::Tensor faces = at::tensor({0, 1, 2, 1, 2, 3}, at::kLong).view({2, 3});
    EXPECT_NO_THROW(check_faces(faces, 4, "m.off"));
    EXPECT_THROW(check_faces(faces, 3, "m.off"), InputError);
}

}  // namespace pumeta
