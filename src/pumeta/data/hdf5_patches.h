// The training patches of the public benchmarks (PU-GAN, PU1K): an HDF5 file with one dataset of
// input patches and one of GT patches, read as a PatchSet (data/patch_set.h).
#pragma once

#include <cstdint>
#include <string>

#include "pumeta/data/patch_set.h"

namespace pumeta {

/// The most points (patches × points per patch) a dataset may hold: 2^28, 3.2 GB as float32
/// xyz (PU1K's GT patches hold 7·10^7). A bound on what a file can make the reader allocate.
inline constexpr int64_t kMaxHdf5PatchPoints = int64_t{1} << 28;

/// Reads the HDF5 file `path`: dataset keys.input holds the input patches, floating-point
/// [P, n, C], and keys.gt the GT patches [P, m, C'], C, C' >= 3: xyz first, further columns
/// (normals) dropped. m must be `ratio`·n (the model's ratio); ratio 0 accepts any whole
/// multiple m = r·n, r >= 2. Dataset keys may name a path inside groups ("data/poisson_256").
///
/// The PatchSet has ratio = m / n, patch_points = n and each GT patch as one "mesh" (id: its
/// index) with one seed, the patch's point nearest its centroid: PatchSet::gt_patch(s) is GT
/// patch s (all m points, ordered by distance to that point), and training draws its inputs
/// from it with the run's sampler, as PU-GAN's training draws them from its GT patches by
/// default (its non-uniform sampler is `sampler: nonuniform`). The input patches fix n and are
/// checked, not kept.
///
/// Every problem is an InputError "<path>: <what>" on one line: a missing file, a file that is
/// not HDF5 or is truncated or damaged, a missing key (naming the datasets the file holds),
/// a dataset that is not floating-point or not of shape [P, n, >=3], holds no stored data or
/// more than kMaxHdf5PatchPoints points, patch counts that differ, m not ratio·n, a
/// non-finite coordinate. HDF5's own error printing is switched off (for the whole process).
PatchSet read_hdf5_patches(const std::string& path, const Hdf5PatchKeys& keys = {},
                           int64_t ratio = 0);

}  // namespace pumeta
