// libFuzzer target: the .stl reader through pumeta's read path (byte order marks included).
#include "fuzz/contract.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
    return pumeta::fuzz::run(data, size, [](std::string_view bytes) {
        pumeta::fuzz::read_geometry_contract("input.stl", bytes);
    });
}
