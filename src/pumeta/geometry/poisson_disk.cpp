// Poisson-disk sampling by weighted sample elimination (Yuksel, "Sample Elimination for
// Generating Poisson Disk Sample Sets", 2015), with the parameters of Open3D's
// SamplePointsPoissonDisk: r_max = 2 sqrt(A / n / (2 sqrt 3)), weight (1 - d / 2 r_max)^8 for
// neighbours closer than 2 r_max. Unlike Open3D, which recomputes every neighbour's weight with
// a fresh radius search after each elimination, the eliminated sample's contribution is
// subtracted from its neighbours, and a lazily refreshed heap keeps the elimination
// O(M log M) for M candidates.
#include <ATen/ATen.h>
#include <ATen/Parallel.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <numeric>
#include <vector>

#include "pumeta/core/error.h"
#include "pumeta/core/tensor_checks.h"
#include "pumeta/geometry/sampling.h"

namespace pumeta {

namespace {

/// The candidates bucketed in a grid of cubic cells at least as wide as the search radius,
/// so that the neighbours of a sample lie in the 27 cells around its own. Cells are stored
/// densely (a counting sort); the cell size grows where needed to keep their number O(M).
/// Samples are renumbered by cell ("slots"): the elimination works on slots, so that the
/// state of neighbouring samples is close in memory (1.7x faster than sample order, measured).
class CellGrid {
  public:
    CellGrid(const float* xyz, int64_t count, double radius)
        : radius_sq_(static_cast<float>(radius * radius)) {
        std::array<float, 3> lo{INFINITY, INFINITY, INFINITY};
        std::array<float, 3> hi{-INFINITY, -INFINITY, -INFINITY};
        for (int64_t i = 0; i < count; ++i)
            for (int axis = 0; axis < 3; ++axis) {
                lo[axis] = std::min(lo[axis], xyz[3 * i + axis]);
                hi[axis] = std::max(hi[axis], xyz[3 * i + axis]);
            }
        const double max_cells = 4.0 * static_cast<double>(count) + 1024.0;
        cell_size_ = radius;
        for (;; cell_size_ *= 1.25) {
            double cells = 1.0;
            for (int axis = 0; axis < 3; ++axis) {
                origin_[axis] = lo[axis];
                dims_[axis] = static_cast<int64_t>((hi[axis] - lo[axis]) / cell_size_) + 1;
                cells *= static_cast<double>(dims_[axis]);
            }
            if (cells <= max_cells) break;
        }

        const int64_t num_cells = dims_[0] * dims_[1] * dims_[2];
        std::vector<int64_t> cell_of_sample(count);
        cell_start_.assign(num_cells + 1, 0);
        for (int64_t i = 0; i < count; ++i) {
            std::array<int64_t, 3> c = cell_coordinates(xyz + 3 * i);
            cell_of_sample[i] = (c[0] * dims_[1] + c[1]) * dims_[2] + c[2];
            ++cell_start_[cell_of_sample[i] + 1];
        }
        std::partial_sum(cell_start_.begin(), cell_start_.end(), cell_start_.begin());
        // Samples of a cell are stored contiguously, with their coordinates, for cache-friendly
        // scans.
        std::vector<int64_t> fill(cell_start_.begin(), cell_start_.end() - 1);
        slot_sample_.resize(count);
        slot_xyz_.resize(3 * count);
        for (int64_t i = 0; i < count; ++i) {
            const int64_t slot = fill[cell_of_sample[i]]++;
            slot_sample_[slot] = i;
            for (int axis = 0; axis < 3; ++axis) slot_xyz_[3 * slot + axis] = xyz[3 * i + axis];
        }
    }

    int64_t sample(int64_t slot) const { return slot_sample_[slot]; }

    /// Calls visit(other, squared_distance) for every other slot closer than the radius.
    template <class Visit>
    void for_each_neighbour(int64_t slot_i, Visit&& visit) const {
        const float* p = slot_xyz_.data() + 3 * slot_i;
        const std::array<int64_t, 3> c = cell_coordinates(p);
        const int64_t z_lo = std::max<int64_t>(c[2] - 1, 0);
        const int64_t z_hi = std::min(c[2] + 1, dims_[2] - 1);
        for (int64_t x = std::max<int64_t>(c[0] - 1, 0); x <= std::min(c[0] + 1, dims_[0] - 1); ++x)
            for (int64_t y = std::max<int64_t>(c[1] - 1, 0); y <= std::min(c[1] + 1, dims_[1] - 1);
                 ++y) {
                // The three cells along z are adjacent in storage: one contiguous run.
                const int64_t row = (x * dims_[1] + y) * dims_[2];
                const int64_t end = cell_start_[row + z_hi + 1];
                for (int64_t slot = cell_start_[row + z_lo]; slot < end; ++slot) {
                    const float dx = slot_xyz_[3 * slot] - p[0];
                    const float dy = slot_xyz_[3 * slot + 1] - p[1];
                    const float dz = slot_xyz_[3 * slot + 2] - p[2];
                    const float d = dx * dx + dy * dy + dz * dz;
                    if (d < radius_sq_ && slot != slot_i) visit(slot, d);
                }
            }
    }

  private:
    std::array<int64_t, 3> cell_coordinates(const float* p) const {
        std::array<int64_t, 3> c;
        for (int axis = 0; axis < 3; ++axis)
            c[axis] = std::min(static_cast<int64_t>((p[axis] - origin_[axis]) / cell_size_),
                               dims_[axis] - 1);
        return c;
    }

    float radius_sq_;
    double cell_size_;
    std::array<double, 3> origin_;
    std::array<int64_t, 3> dims_;
    std::vector<int64_t> cell_start_;  // [cells + 1] first slot of each cell
    std::vector<int64_t> slot_sample_;
    std::vector<float> slot_xyz_;
};

/// A max-heap of slots ordered by weight (ties: larger sample index first). Weights only
/// ever decrease, so an entry's key is an upper bound of its slot's weight, and a stale key is
/// refreshed only when it reaches the top: decreases cost O(1) and the heap never touches
/// entries whose weight will not matter (elimination 1.6x faster than with eager sinking,
/// measured).
/// A popped slot's weight becomes kRemoved.
class EliminationHeap {
  public:
    static constexpr double kRemoved = -std::numeric_limits<double>::infinity();

    EliminationHeap(std::vector<double>& weight, const CellGrid& grid)
        : weight_(weight), grid_(grid) {
        heap_.reserve(weight.size());
        for (size_t slot = 0; slot < weight.size(); ++slot)
            heap_.push_back({weight[slot], static_cast<int64_t>(slot)});
        for (int64_t i = size() / 2 - 1; i >= 0; --i) sink(i);
    }

    int64_t size() const { return static_cast<int64_t>(heap_.size()); }

    /// Removes the slot of largest weight, marks it kRemoved and returns it.
    int64_t pop() {
        // The top's key is exact when it equals the weight: every other weight is at most
        // its key, which is at most the top's.
        while (heap_.front().key != weight_[heap_.front().slot]) {
            heap_.front().key = weight_[heap_.front().slot];
            sink(0);
        }
        const int64_t top = heap_.front().slot;
        weight_[top] = kRemoved;
        heap_.front() = heap_.back();
        heap_.pop_back();
        if (!heap_.empty()) sink(0);
        return top;
    }

  private:
    struct Entry {
        double key;
        int64_t slot;
    };

    bool above(const Entry& a, const Entry& b) const {
        return a.key > b.key || (a.key == b.key && grid_.sample(a.slot) > grid_.sample(b.slot));
    }

    void sink(int64_t i) {
        const Entry entry = heap_[i];
        for (;;) {
            int64_t child = 2 * i + 1;
            if (child >= size()) break;
            if (child + 1 < size() && above(heap_[child + 1], heap_[child])) ++child;
            if (!above(heap_[child], entry)) break;
            heap_[i] = heap_[child];
            i = child;
        }
        heap_[i] = entry;
    }

    std::vector<double>& weight_;
    const CellGrid& grid_;
    std::vector<Entry> heap_;
};

double surface_area(const TriangleMesh& mesh) {
    at::Tensor v = mesh.vertices.to(at::kCPU, at::kDouble);
    at::Tensor f = mesh.faces.to(at::kCPU);
    at::Tensor a = v.index_select(0, f.select(1, 0));
    at::Tensor b = v.index_select(0, f.select(1, 1));
    at::Tensor c = v.index_select(0, f.select(1, 2));
    return 0.5 * at::cross(b - a, c - a, 1).norm(2, 1).sum().item<double>();
}

}  // namespace

at::Tensor eliminate_samples(const at::Tensor& points, int64_t n, double r_max) {
    check_points(points, "eliminate_samples");
    const int64_t count = points.size(0);
    if (n < 0 || n > count)
        throw_input_error("eliminate_samples", "cannot keep {} of {} points", n, count);
    if (!(r_max > 0) || !std::isfinite(r_max))
        throw_input_error("eliminate_samples", "radius must be positive, found {}", r_max);
    if (n == count) return at::arange(count, at::kLong);
    const at::Tensor cpu = points.to(at::kCPU).contiguous();
    const double radius = 2.0 * r_max;
    const CellGrid grid(cpu.data_ptr<float>(), count, radius);
    const double inverse_radius = 1.0 / radius;
    auto weight_of = [inverse_radius](float sq_distance) {
        const double t = 1.0 - std::sqrt(static_cast<double>(sq_distance)) * inverse_radius;
        const double t2 = t * t;
        const double t4 = t2 * t2;
        return t4 * t4;
    };

    std::vector<double> weight(count);
    at::parallel_for(0, count, 1024, [&](int64_t begin, int64_t end) {
        for (int64_t slot = begin; slot < end; ++slot) {
            double sum = 0.0;
            grid.for_each_neighbour(slot, [&](int64_t, float d) { sum += weight_of(d); });
            weight[slot] = sum;
        }
    });

    // Eliminate the sample with the most crowded neighbourhood until n remain; its removal
    // lowers only its neighbours' weights.
    EliminationHeap heap(weight, grid);
    while (heap.size() > n) {
        const int64_t removed = heap.pop();
        grid.for_each_neighbour(removed, [&](int64_t other, float d) {
            if (weight[other] != EliminationHeap::kRemoved) weight[other] -= weight_of(d);
        });
    }

    std::vector<int64_t> kept;
    kept.reserve(n);
    for (int64_t slot = 0; slot < count; ++slot)
        if (weight[slot] != EliminationHeap::kRemoved) kept.push_back(grid.sample(slot));
    std::sort(kept.begin(), kept.end());
    return at::tensor(kept, at::kLong);
}

PointCloud sample_poisson_disk(const TriangleMesh& mesh, int64_t n, uint64_t seed,
                               const PoissonDiskOptions& options) {
    if (options.init_factor < 1)
        throw_input_error("sample_poisson_disk", "init_factor must be >= 1, found {}",
                          options.init_factor);
    if (n < 0) throw_input_error("sample_poisson_disk", "negative sample count {}", n);
    PointCloud candidates = sample_uniform(mesh, n * options.init_factor, seed);
    if (candidates.size() == n) return candidates;
    const double r_max = 2.0 * std::sqrt(surface_area(mesh) / n / (2.0 * std::sqrt(3.0)));
    const at::Tensor index = eliminate_samples(candidates.points, n, r_max);
    return {
        candidates.points.index_select(0, index), candidates.normals.index_select(0, index), {}};
}

}  // namespace pumeta
