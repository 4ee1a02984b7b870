// Kernel maps: for each offset of a convolution kernel, the pairs (input row, output row) of
// active sites it connects. A sparse convolution is then, per offset k,
//   out[out_k] += in[in_k] · W_k
// (gather, GEMM, scatter-add), which plain ATen ops differentiate to any order.
#pragma once

#include <ATen/core/Tensor.h>

#include <array>
#include <cstdint>
#include <vector>

#include "pumeta/nn/sparse/coordinate_hash.h"

namespace pumeta {

class CoordinateSet;

/// The offsets of a cubic kernel of odd size K, in units of one step: (a-h, b-h, c-h) for
/// a, b, c in [0, K) with h = (K-1)/2, x slowest, so that offset index (a·K + b)·K + c matches
/// the [K,K,K] spatial layout of a dense conv3d weight (x, y, z as D, H, W).
std::vector<std::array<int64_t, 3>> kernel_offsets(int64_t kernel_size);

/// InputError "<context>: ..." unless kernel_size is odd and >= 1.
void check_kernel_size(int64_t kernel_size, const char* context);

struct KernelMap {
    /// Per kernel offset: int64 [P_k] rows of the input set and of the output set.
    std::vector<at::Tensor> in;
    std::vector<at::Tensor> out;
    /// Index of the offset that maps every row to itself (the centre of a stride-1 map), whose
    /// gather and scatter a convolution can skip; -1 when there is none.
    int64_t identity_offset = -1;
    int64_t input_size = 0;
    int64_t output_size = 0;
    /// The non-identity offsets padded to one length P, so that a convolution runs them as one
    /// batched GEMM rather than one GEMM per offset (per-op overhead dominates small maps):
    /// offsets int64 [K'], in and out int64 [K'·P] whose padding reads row input_size (a zero
    /// row) and writes row output_size (dropped). Undefined where padding would waste too much.
    at::Tensor batched_offsets;
    at::Tensor batched_in;
    at::Tensor batched_out;

    /// The same map output-major, for maps dense enough that one GEMM over every (output,
    /// offset) slot, with zeros where a site has no neighbour, beats a gather-GEMM-scatter per
    /// offset (narrow layers pay per scattered row, whatever its width):
    ///   gather_table  int32 [output_size, K]: the input row output o reads through offset k,
    ///                 or -1;
    ///   scatter_table int32 [input_size, K]: the output row input i feeds through offset k,
    ///                 or -1 (the gather table of the transposed map).
    /// Undefined where the slots outnumber the pairs too much (see prepare_tables).
    at::Tensor gather_table;
    at::Tensor scatter_table;

    int64_t kernel_volume() const { return int64_t(in.size()); }
    /// Total number of (input, output) pairs over all offsets.
    int64_t pairs() const;
    /// The map of the transposed convolution: inputs and outputs swapped.
    KernelMap transposed() const;
    /// Fills the batched_* fields when the padded pairs are few (under 2^15) or at most 25%
    /// more than the real ones. Called by the builders below.
    void prepare_batched();
    /// Fills gather_table and scatter_table when the pairs fill at least a third of the
    /// output slots (output_size · K). Called by the builders below.
    void prepare_tables();
};

/// Stride-1 map of `set` onto itself: input = output + offset·dilation·stride.
KernelMap build_conv_map(const CoordinateSet& set, int64_t kernel_size, int64_t dilation);

/// Strided map from `fine` (stride s) to `coarse` (stride s·f, from fine.coarser(f)):
/// input (fine) = output (coarse) + offset·s, as MinkowskiEngine's strided convolution.
KernelMap build_down_map(const CoordinateSet& fine, const CoordinateSet& coarse,
                         int64_t kernel_size);

/// Generative transposed map (MinkowskiEngine's generate_new_coords): every coarse site c
/// (stride S) reaches c + offset·(S/f) for all offsets. Returns the new coordinates, int32
/// [G,4] in first-occurrence order (coarse row, then offset), their hash map, and the map
/// coarse -> new. InputError when a new site leaves the packable range.
struct GeneratedCoordinates {
    at::Tensor coords;
    CoordinateHash hash;
    KernelMap map;
};
GeneratedCoordinates generate_coordinates(const CoordinateSet& coarse, int64_t kernel_size,
                                          int64_t factor);

}  // namespace pumeta
