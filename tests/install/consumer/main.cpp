// Built against an installed pumeta by tests/install/run.sh: loads the shipped default model,
// upsamples a sphere, writes and reads the result back and checks it against the sphere.
// Prints one line; exits 1 with a message on any failure.
#include <pumeta/pumeta.h>

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <exception>
#include <string>

namespace {

/// n points spread evenly over the unit sphere (a Fibonacci lattice).
pumeta::Points sphere(int n) {
    const double angle = std::acos(-1.0) * (3.0 - std::sqrt(5.0));
    pumeta::Points points;
    for (int i = 0; i < n; ++i) {
        const double z = 1.0 - (2.0 * i + 1.0) / n;
        const double r = std::sqrt(1.0 - z * z);
        points.push_back({static_cast<float>(r * std::cos(angle * i)),
                          static_cast<float>(r * std::sin(angle * i)), static_cast<float>(z)});
    }
    return points;
}

int fail(const std::string& message) {
    std::fprintf(stderr, "consumer: %s\n", message.c_str());
    return 1;
}

}  // namespace

int main(int argc, char** argv) {
    if (argc != 3) return fail("usage: consumer INSTALL_PREFIX TEMP_DIR");
    const std::string prefix = argv[1];
    const std::string file = std::string(argv[2]) + "/dense.ply";
    setenv("PUMETA_MODELS", PUMETA_PACKAGE_MODELS_DIR, /*overwrite=*/0);
    try {
        const pumeta::Model model;  // the shipped default model for the default ratio
        if (model.path().rfind(prefix + "/", 0) != 0)
            return fail("loaded " + model.path() + ", not a model installed under " + prefix);
        const pumeta::Points input = sphere(512);
        const pumeta::Points output = pumeta::upsample(model, input);
        const size_t expected = input.size() * static_cast<size_t>(model.ratio());
        if (output.size() != expected)
            return fail("upsampled to " + std::to_string(output.size()) + " points, expected " +
                        std::to_string(expected));
        pumeta::write_points(file, pumeta::to_tensor(output));
        const at::Tensor dense = pumeta::read_points(file);
        // Denser points on the same surface: closer to a fine sample of it than the input.
        const at::Tensor surface = pumeta::to_tensor(sphere(16384));
        const double cd_input = pumeta::metrics(pumeta::to_tensor(input), surface).cd;
        const double cd_output = pumeta::metrics(dense, surface).cd;
        if (!std::isfinite(cd_output) || !(cd_output < cd_input))
            return fail("CD to the sphere " + std::to_string(cd_output) + ", the input's " +
                        std::to_string(cd_input));
        std::printf(
            "consumer: %s (%s, %lldx) %zu -> %lld points, CD to the sphere %.3e (input %.3e)\n",
            model.path().c_str(), model.backbone().c_str(), static_cast<long long>(model.ratio()),
            input.size(), static_cast<long long>(dense.size(0)), cd_output, cd_input);
    } catch (const std::exception& e) {
        return fail(e.what());
    }
    return 0;
}
