// Earth mover's distance between two equally sized point clouds as a training loss (PU-GAN's
// reconstruction term): a one-to-one matching found without gradient tracking, then the
// matched distances recomputed from coordinate differences.
#pragma once

#include <ATen/core/Tensor.h>

#include <cstdint>

namespace pumeta {

/// How the matching is found.
enum class EmdMatching {
    /// Bertsekas' auction with ε-scaling: a one-to-one assignment whose cost is within
    /// n·epsilon of the optimum. The assignment is locally constant in the points, so the
    /// loss computed with it held constant has exactly the loss's derivatives (first and
    /// second order) wherever the assignment does not switch.
    kAuction,
    /// Fan et al.'s approximate matching (PU-GAN's `approxmatch` CPU kernel): a soft plan
    /// built greedily over 11 rounds of temperatures −4^j (j = 8 … −1, then 0). The plan moves
    /// with the points, so holding it constant (as the original does) gives the gradient of
    /// a surrogate, not of the value computed.
    kApproximate,
};

struct EmdOptions {
    EmdMatching matching = EmdMatching::kAuction;
    /// Auction only: the final bid increment, in the points' units. The matched mean distance
    /// exceeds the optimal one by at most epsilon.
    double epsilon = 1e-4;
};

/// The matching of a [n,3] to b [n,3] per batch element: for a, b float or double [B,n,3],
/// a plan float64 [B,n,n] whose row i holds the mass point i of `a` sends to each point of
/// `b` (every row and column sums to 1 for the auction, a permutation matrix; at most 1 for
/// the approximate matching, whose capacity clipping can leave some mass unassigned).
/// No gradient tracking. InputError for clouds of different shapes.
at::Tensor emd_plan(const at::Tensor& a, const at::Tensor& b, const EmdOptions& options = {});

/// mean over the batch and the n points of Σ_j plan_ij · |pred_i − target_j| (Euclidean,
/// not squared; PU-GAN's cost / 1024 at 4× for unit-radius patches) with the plan of
/// emd_plan(pred, target) held constant. pred, target [B,n,3] float or double; a scalar.
/// Distances are sqrt(|d|² + 1e-12), so the loss is differentiable twice even where matched
/// points coincide. The approximate plan is used where it exceeds 1e-9 (dense rows).
at::Tensor emd_loss(const at::Tensor& pred, const at::Tensor& target,
                    const EmdOptions& options = {});

}  // namespace pumeta
