#include "pumeta/nn/parameters.h"

#include <limits>

#include "pumeta/core/error.h"

namespace pumeta {

const at::Tensor& param(const ParamMap& params, const std::string& name) {
    auto it = params.find(name);
    if (it == params.end()) throw InternalError("missing parameter '" + name + "'");
    return it->second;
}

int64_t count_parameters(const ParamMap& params) {
    int64_t total = 0;
    for (const auto& [name, tensor] : params) total += tensor.numel();
    return total;
}

namespace {

struct Budget {
    int64_t remaining = 0;
    std::string source;
};
thread_local Budget* active_budget = nullptr;

}  // namespace

ParameterBudget::ParameterBudget(int64_t elements, std::string source) {
    if (active_budget) throw InternalError("parameter budgets do not nest");
    active_budget = new Budget{elements, std::move(source)};
}

ParameterBudget::~ParameterBudget() {
    delete active_budget;
    active_budget = nullptr;
}

void reserve_parameter(at::IntArrayRef shape) {
    if (!active_budget) return;
    int64_t elements = 1;
    for (int64_t size : shape)
        if (size < 0 || __builtin_mul_overflow(elements, size, &elements))
            elements = std::numeric_limits<int64_t>::max();
    if (elements > active_budget->remaining)
        throw_input_error(active_budget->source,
                          "it builds a network larger than the file's tensors (a tensor of {} "
                          "values with {} left)",
                          elements, active_budget->remaining);
    active_budget->remaining -= elements;
}

}  // namespace pumeta
