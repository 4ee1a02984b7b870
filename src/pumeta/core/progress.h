// A progress bar for long work, drawn on stderr only when stderr is a terminal.
#pragma once

#include <chrono>
#include <cstdint>
#include <string>

namespace pumeta {

class ProgressBar {
  public:
    /// total: number of units of work; label: shown before the bar.
    ProgressBar(int64_t total, std::string label);
    ~ProgressBar();

    /// Advances to `done` units; `status` (e.g. "loss 1.2e-3") is shown after the bar.
    /// Redraws at most 10 times per second.
    void update(int64_t done, const std::string& status = "");
    /// Draws the final state and ends the line.
    void finish(const std::string& status = "");

    /// Whether the bar draws anything (stderr is a terminal and PUMETA_NO_PROGRESS is unset).
    static bool enabled();

  private:
    void draw(const std::string& status);

    int64_t total_;
    int64_t done_ = 0;
    std::string label_;
    bool enabled_;
    bool finished_ = false;
    std::chrono::steady_clock::time_point start_;
    std::chrono::steady_clock::time_point last_draw_;
};

}  // namespace pumeta
