// The debiased, unbalanced Sinkhorn divergence between point clouds (Feydy et al. 2019;
// Séjourné et al. 2019), as geomloss's SamplesLoss("sinkhorn", p=2, blur, reach) computes it:
// cost ½|x − y|², entropic regularisation ε = blur², marginal KL penalty ρ = reach², uniform
// weights, log-domain symmetric iterations with ε-scaling. Meta-PU's training loss.
#pragma once

#include <ATen/core/Tensor.h>

#include <cstdint>

namespace pumeta {

/// How the divergence is differentiated.
enum class SinkhornGradient {
    /// The iterations run without a graph; the final potentials are re-expressed at the points
    /// with everything else detached (the other cloud, the potentials they were computed
    /// from), as geomloss's last extrapolation. First order: the envelope theorem's gradient
    /// Σ_j π_ij (x_i − y_j), exact once the potentials have converged. Second order sees the
    /// explicit dependence of those formulas on the points (the transported mass e^{−f/ρ}
    /// and the quadratic cost; not the softmax covariance, nor how the potentials move with
    /// the points). Memory O(N + M) per cloud beyond one block of costs.
    kEnvelope,
    /// Autograd through every iteration: exact derivatives of every order of the computed
    /// value, at O(iterations · N · M) memory. For small clouds (tests, small inner loops).
    kUnrolled,
};

struct SinkhornOptions {
    /// ε = blur² (> 0): the scale below which the transport plan blurs.
    double blur = 1e-3;
    /// ρ = reach² (> 0): mass farther than about `reach` is destroyed/created at KL cost
    /// instead of transported.
    double reach = 0.2;
    /// ε-scaling: the blur shrinks by this factor per iteration (0 < scaling < 1), from the
    /// diameter of the two clouds (bounding-box diagonal) down to `blur`.
    double scaling = 0.5;
    /// Symmetric iterations at ε = blur² after the schedule (geomloss: 0)...
    int64_t extra_iterations = 0;
    /// ...stopping early once no potential moves by more than this.
    double tolerance = 0;
    SinkhornGradient gradient = SinkhornGradient::kEnvelope;
};

/// S_ε,ρ(x, y) = OT(x, y) − ½ OT(x, x) − ½ OT(y, y) for uniform weights 1/N and 1/M, written
/// as (ρ + ε/2)·(⟨a, e^{−f_xx/ρ} − e^{−f_xy/ρ}⟩ + ⟨b, e^{−g_yy/ρ} − e^{−g_yx/ρ}⟩) with the
/// final potentials; the mean over the batch. x [B,N,3] and y [B,M,3] of one floating type
/// (float or double), N, M >= 1. Identical clouds give 0. Costs are computed in blocks of
/// at most 2^22 pairs outside the graph (kEnvelope); kUnrolled keeps them all.
at::Tensor sinkhorn_divergence(const at::Tensor& x, const at::Tensor& y,
                               const SinkhornOptions& options = {});

}  // namespace pumeta
