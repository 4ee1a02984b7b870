#include "pumeta/nn/sparse/kernel_map.h"

#include <ATen/ATen.h>
#include <ATen/Parallel.h>

#include <algorithm>
#include <limits>

#include "pumeta/core/error.h"
#include "pumeta/nn/sparse/coordinate_set.h"

namespace pumeta {

namespace {

at::Tensor to_index_tensor(const std::vector<int64_t>& values) {
    at::Tensor t = at::empty({int64_t(values.size())}, at::kLong);
    std::copy(values.begin(), values.end(), t.data_ptr<int64_t>());
    return t;
}

/// Appends the pairs of every shift: output row o (coordinates `out_coords`) reads the input
/// site at its coordinates + shift, where one exists. One parallel pass over the outputs for
/// all shifts (a pass per shift would pay the thread pool's barrier per offset).
void append_offsets(KernelMap& map, const CoordinateSet& input, const at::Tensor& out_coords,
                    const std::vector<std::array<int64_t, 3>>& shifts) {
    const int64_t count = out_coords.size(0), volume = int64_t(shifts.size());
    const int32_t* c = out_coords.data_ptr<int32_t>();
    std::vector<int64_t> found(count * volume);
    at::parallel_for(0, count, 1024, [&](int64_t begin, int64_t end) {
        for (int64_t o = begin; o < end; ++o) {
            const int32_t* row = c + 4 * o;
            for (int64_t k = 0; k < volume; ++k)
                found[k * count + o] = input.find(row[0], row[1] + shifts[k][0],
                                                  row[2] + shifts[k][1], row[3] + shifts[k][2]);
        }
    });
    for (int64_t k = 0; k < volume; ++k) {
        std::vector<int64_t> in_rows, out_rows;
        for (int64_t o = 0; o < count; ++o) {
            const int64_t i = found[k * count + o];
            if (i < 0) continue;
            in_rows.push_back(i);
            out_rows.push_back(o);
        }
        map.in.push_back(to_index_tensor(in_rows));
        map.out.push_back(to_index_tensor(out_rows));
    }
}

/// The kernel's offsets times `step`.
std::vector<std::array<int64_t, 3>> scaled_offsets(int64_t kernel_size, int64_t step) {
    std::vector<std::array<int64_t, 3>> shifts;
    for (const auto& offset : kernel_offsets(kernel_size))
        shifts.push_back({offset[0] * step, offset[1] * step, offset[2] * step});
    return shifts;
}

}  // namespace

void check_kernel_size(int64_t kernel_size, const char* context) {
    if (kernel_size < 1 || kernel_size % 2 == 0)
        throw_input_error(context, "kernel size must be odd and >= 1, found {}", kernel_size);
}

std::vector<std::array<int64_t, 3>> kernel_offsets(int64_t kernel_size) {
    check_kernel_size(kernel_size, "kernel offsets");
    const int64_t half = (kernel_size - 1) / 2;
    std::vector<std::array<int64_t, 3>> offsets;
    for (int64_t a = 0; a < kernel_size; ++a)
        for (int64_t b = 0; b < kernel_size; ++b)
            for (int64_t c = 0; c < kernel_size; ++c)
                offsets.push_back({a - half, b - half, c - half});
    return offsets;
}

int64_t KernelMap::pairs() const {
    int64_t total = 0;
    for (const at::Tensor& t : in) total += t.numel();
    return total;
}

KernelMap KernelMap::transposed() const {
    KernelMap t;
    t.in = out;
    t.out = in;
    t.identity_offset = identity_offset;
    t.input_size = output_size;
    t.output_size = input_size;
    // The padding rows swap with the sizes, so the padded pairs transpose too.
    t.batched_offsets = batched_offsets;
    t.batched_in = batched_out;
    t.batched_out = batched_in;
    t.gather_table = scatter_table;
    t.scatter_table = gather_table;
    return t;
}

void KernelMap::prepare_tables() {
    const int64_t volume = kernel_volume();
    // Below a third, the zero slots' GEMM work outweighs what the scatters cost
    // (bench_nn_sparse_conv compares both paths).
    if (volume == 0 || 3 * pairs() < output_size * volume ||
        std::max(input_size, output_size) > std::numeric_limits<int32_t>::max())
        return;
    gather_table = at::full({output_size, volume}, -1, at::kInt);
    scatter_table = at::full({input_size, volume}, -1, at::kInt);
    int32_t* gather = gather_table.data_ptr<int32_t>();
    int32_t* scatter = scatter_table.data_ptr<int32_t>();
    for (int64_t k = 0; k < volume; ++k) {
        const int64_t* i = in[k].data_ptr<int64_t>();
        const int64_t* o = out[k].data_ptr<int64_t>();
        for (int64_t p = 0; p < in[k].numel(); ++p) {
            gather[o[p] * volume + k] = int32_t(i[p]);
            scatter[i[p] * volume + k] = int32_t(o[p]);
        }
    }
}

void KernelMap::prepare_batched() {
    std::vector<int64_t> offsets;
    int64_t longest = 0, total = 0;
    for (int64_t k = 0; k < kernel_volume(); ++k) {
        if (k == identity_offset || in[k].numel() == 0) continue;
        offsets.push_back(k);
        longest = std::max(longest, in[k].numel());
        total += in[k].numel();
    }
    const int64_t padded = longest * int64_t(offsets.size());
    if (offsets.empty() || (padded >= (1 << 15) && 4 * padded > 5 * total)) return;
    batched_offsets = to_index_tensor(offsets);
    batched_in = at::full({padded}, input_size, at::kLong);
    batched_out = at::full({padded}, output_size, at::kLong);
    for (size_t j = 0; j < offsets.size(); ++j) {
        const int64_t k = offsets[j], count = in[k].numel();
        batched_in.narrow(0, int64_t(j) * longest, count).copy_(in[k]);
        batched_out.narrow(0, int64_t(j) * longest, count).copy_(out[k]);
    }
}

KernelMap build_conv_map(const CoordinateSet& set, int64_t kernel_size, int64_t dilation) {
    KernelMap map;
    map.input_size = map.output_size = set.size();
    append_offsets(map, set, set.coords(), scaled_offsets(kernel_size, dilation * set.stride()));
    map.identity_offset = map.kernel_volume() / 2;
    map.prepare_batched();
    map.prepare_tables();
    return map;
}

KernelMap build_down_map(const CoordinateSet& fine, const CoordinateSet& coarse,
                         int64_t kernel_size) {
    KernelMap map;
    map.input_size = fine.size();
    map.output_size = coarse.size();
    append_offsets(map, fine, coarse.coords(), scaled_offsets(kernel_size, fine.stride()));
    map.prepare_batched();
    map.prepare_tables();
    return map;
}

GeneratedCoordinates generate_coordinates(const CoordinateSet& coarse, int64_t kernel_size,
                                          int64_t factor) {
    const auto offsets = kernel_offsets(kernel_size);
    const int64_t volume = int64_t(offsets.size());
    const int64_t step = coarse.stride() / factor;
    const int64_t count = coarse.size();
    const int32_t* c = coarse.coords().data_ptr<int32_t>();

    CoordinateHash hash(count * volume / 4);
    std::vector<int32_t> sites;
    std::vector<std::vector<int64_t>> out_rows(volume, std::vector<int64_t>(count));
    for (int64_t i = 0; i < count; ++i) {
        const int32_t* row = c + 4 * i;
        for (int64_t k = 0; k < volume; ++k) {
            int64_t x = row[1] + offsets[k][0] * step, y = row[2] + offsets[k][1] * step,
                    z = row[3] + offsets[k][2] * step;
            if (!packable(row[0], x, y, z))
                throw_input_error("sparse coordinates",
                                  "generated site ({}, {}, {}) leaves the coordinate range", x, y,
                                  z);
            int64_t next = int64_t(sites.size() / 4);
            int64_t stored = hash.insert(pack_coordinate(row[0], x, y, z), next);
            if (stored == next)
                sites.insert(sites.end(), {row[0], int32_t(x), int32_t(y), int32_t(z)});
            out_rows[k][i] = stored;
        }
    }
    GeneratedCoordinates result{
        at::empty({int64_t(sites.size() / 4), 4}, at::kInt), std::move(hash), {}};
    std::copy(sites.begin(), sites.end(), result.coords.data_ptr<int32_t>());
    at::Tensor all_coarse = at::arange(count, at::kLong);
    for (int64_t k = 0; k < volume; ++k) {
        result.map.in.push_back(all_coarse);
        result.map.out.push_back(to_index_tensor(out_rows[k]));
    }
    result.map.input_size = count;
    result.map.output_size = result.coords.size(0);
    result.map.prepare_batched();
    result.map.prepare_tables();
    return result;
}

}  // namespace pumeta
