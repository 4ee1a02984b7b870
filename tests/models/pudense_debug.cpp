#include "pumeta/models/pudense.h"
#include <ATen/ATen.h>
#include <gtest/gtest.h>
#include <chrono>
#include <iostream>
#include <torch/csrc/autograd/profiler_legacy.h>
#include "pumeta/nn/gradients.h"
namespace pumeta {
double now() { return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count(); }
at::Tensor patches(int64_t b, int64_t n, uint64_t seed) {
    at::Generator gen = at::detail::createCPUGenerator(seed);
    at::Tensor r = at::sqrt(at::rand({b, n}, gen)), a = at::rand({b, n}, gen) * 6.2832;
    at::Tensor u = r * at::cos(a), v = r * at::sin(a);
    return at::stack({u, v, 0.3 * at::sin(2 * u) * at::cos(v)}, -1);
}
TEST(Dbg, Time) {
    PuDense model(PuDenseOptions::from_json({{"preset", "compact"}, {"ratio", 8}}));
    at::Tensor gt = patches(2, 2048, 1);
    at::Tensor x = gt.narrow(1, 0, 256);
    double t0 = now();
    auto vox = model.voxels(x);
    double t1 = now();
    { at::NoGradGuard ng; model.loss(x, gt, model.parameters()); }
    double t2 = now();
    { at::NoGradGuard ng; model.loss(x, gt, model.parameters()); }
    double t3 = now();
    gradients(model.loss(x, gt, model.parameters()), model.parameters());
    double t4 = now();
    std::cerr << "voxels " << vox->size() << " vox " << t1-t0 << " first fwd " << t2 - t1 << " second fwd " << t3 - t2 << " fwd+bwd " << t4 - t3 << "\n";
    Occupancy occ = model.occupancy(vox, model.parameters(), {});
    std::cerr << "generated " << occ.sites->size() << " stride2 " << vox->coarser(2)->size() << "\n";
    {
        torch::autograd::profiler::RecordProfile guard("/tmp/pudense_trace.json");
        gradients(model.loss(x, gt, model.parameters()), model.parameters());
    }
}
}
