// Random numbers for the shape generator.
#pragma once

#include <cstdint>
#include <random>

namespace pumeta::shapes {

/// Uniform draws from std::mt19937_64. The engine's output sequence is fixed by the C++
/// standard but the std distributions are not, so these are computed here: the same seed then
/// gives the same shapes with any standard library.
class Rng {
  public:
    explicit Rng(uint64_t seed) : engine_(seed) {}

    /// Uniform in [0, 1) with 53 random bits.
    double uniform() { return static_cast<double>(engine_() >> 11) * 0x1.0p-53; }
    double uniform(double lo, double hi) { return lo + (hi - lo) * uniform(); }
    /// Uniform integer in [lo, hi], inclusive.
    int integer(int lo, int hi) {
        return lo + static_cast<int>(engine_() % static_cast<uint64_t>(hi - lo + 1));
    }
    bool chance(double probability) { return uniform() < probability; }
    /// -1 or +1.
    double sign() { return chance(0.5) ? 1.0 : -1.0; }

  private:
    std::mt19937_64 engine_;
};

}  // namespace pumeta::shapes
