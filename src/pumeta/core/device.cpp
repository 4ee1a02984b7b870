#include "pumeta/core/device.h"

#include <ATen/Context.h>

#include "pumeta/core/error.h"

namespace pumeta {

bool cuda_available() { return at::hasCUDA(); }

std::string parse_device(const std::string& device) {
    if (device == "cpu") return "cpu";
    if (device.rfind("cuda", 0) == 0) {
        if (!cuda_available())
            throw_input_error("--device",
                              "'{}' requested but this LibTorch build sees no CUDA device", device);
        if (device == "cuda") return "cuda:0";
        if (device.size() > 5 && device[4] == ':' &&
            device.find_first_not_of("0123456789", 5) == std::string::npos)
            return device;
    }
    throw_input_error("--device", "unknown device '{}' (expected cpu, cuda or cuda:N)", device);
}

}  // namespace pumeta
