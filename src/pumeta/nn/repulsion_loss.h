// PU-Net's repulsion loss, which pushes generated points apart where they crowd.
#pragma once

#include <ATen/core/Tensor.h>

#include <cstdint>

namespace pumeta {

/// mean over points i and their `neighbors` nearest other points j of max(0, h − |p_i − p_j|²)
/// (PU-Net / Dis-PU `get_repulsion_loss` with its defaults: 4 neighbours, h = 0.001).
/// points [B,N,3] float or double with N > neighbors >= 1; returns a scalar.
/// The neighbours are found without gradient tracking (kd-trees on a float32 copy); the
/// distances to them are recomputed from coordinate differences, so the loss is
/// differentiable twice. The original takes the neighbours from a ball query (radius 0.07,
/// at most 20 points, padded with repeated indices when fewer are found); with h = 0.001 only
/// neighbours closer than 0.032 contribute, so the true nearest ones are what it intends.
at::Tensor repulsion_loss(const at::Tensor& points, int64_t neighbors = 4, double h = 1e-3);

/// PU-Net's own form (its get_repulsion_loss4, which Meta-PU trains with): mean over points i
/// and their `neighbors` nearest others j of radius − d·exp(−d²/h²), d = |p_i − p_j| (at
/// least 1e-6). Same neighbour search and shapes as repulsion_loss. The original takes the
/// neighbours from a ball query (radius, first 20 points); the nearest ones are what it
/// intends, and beyond 2h the weight has vanished.
at::Tensor punet_repulsion_loss(const at::Tensor& points, int64_t neighbors = 4,
                                double radius = 0.07, double h = 0.03);

}  // namespace pumeta
