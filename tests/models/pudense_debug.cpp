#include "pumeta/models/pudense.h"
#include <ATen/ATen.h>
#include <ATen/Parallel.h>
#include <gtest/gtest.h>
#include <chrono>
#include <iostream>
#include <torch/csrc/autograd/profiler_legacy.h>
#include "pumeta/nn/gradients.h"
namespace pumeta {
double now() { return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count(); }
double cpu() { return double(clock()) / CLOCKS_PER_SEC; }
at::Tensor patches(int64_t b, int64_t n, uint64_t seed) {
    at::Generator gen = at::detail::createCPUGenerator(seed);
    at::Tensor r = at::sqrt(at::rand({b, n}, gen)), a = at::rand({b, n}, gen) * 6.2832;
    at::Tensor u = r * at::cos(a), v = r * at::sin(a);
    return at::stack({u, v, 0.3 * at::sin(2 * u) * at::cos(v)}, -1);
}
TEST(Dbg, Time) {
    at::set_num_threads(2);
    PuDense model(PuDenseOptions::from_json({{"preset", "compact"}, {"ratio", 8}}));
    at::Tensor gt = patches(8, 2048, 1);
    at::Tensor x = gt.narrow(1, 0, 256);
    { at::NoGradGuard ng; model.loss(x, gt, model.parameters()); }
    double c0 = cpu();
    { at::NoGradGuard ng; model.loss(x.clone() + 0, gt, model.parameters()); }
    double c1 = cpu();
    gradients(model.loss(x, gt, model.parameters()), model.parameters());
    double c2 = cpu();
    std::cerr << "cpu fwd(cached maps) " << c1 - c0 << " fwd+bwd " << c2 - c1 << "\n";
    auto vox = model.voxels(x);
    double c3 = cpu();
    auto fresh = CoordinateSet::create(vox->coords(), 1);
    Occupancy occ = model.occupancy(fresh, model.parameters(), {});
    double c4 = cpu();
    std::cerr << "fwd with fresh maps " << c4 - c3 << " generated " << occ.sites->size() << "\n";
    auto g = occ.sites;
    double c5 = cpu();
    for (int d : {1, 6, 12, 18}) { auto m = CoordinateSet::create(g->coords(), 1)->conv_map(3, d); std::cerr << "d" << d << " pairs " << m->pairs() << " batched " << m->batched_offsets.defined() << "\n"; }
    double c6 = cpu();
    std::cerr << "generated-level maps " << c6 - c5 << "\n";
    {
        torch::autograd::profiler::RecordProfile guard("/tmp/pudense_trace.json");
        gradients(model.loss(x, gt, model.parameters()), model.parameters());
    }
}
}
