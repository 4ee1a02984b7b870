// libFuzzer target: the torch.save archive reader behind `pumeta import` (a zip directory and
// records, then the pickle machine). Whatever it reads must be a state dict of contiguous
// float32 or int64 tensors.
#include "fuzz/contract.h"
#include "pumeta/models/torch_archive.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
    return pumeta::fuzz::run(data, size, [](std::string_view bytes) {
        for (const auto& [name, tensor] : pumeta::parse_torch_state_dict("input.pth", bytes)) {
            if (!tensor.is_contiguous()) pumeta::fuzz::violated(name + " is not contiguous");
            if (tensor.scalar_type() != at::kFloat && tensor.scalar_type() != at::kLong)
                pumeta::fuzz::violated(name + " is neither float32 nor int64");
        }
    });
}
