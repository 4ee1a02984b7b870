#include "pumeta/core/progress.h"

#include <fmt/format.h>
#include <unistd.h>

#include <cstdio>
#include <cstdlib>

namespace pumeta {

namespace {

std::string format_duration(double seconds) {
    if (!(seconds >= 0) || seconds > 1e7) return "--:--";
    auto s = static_cast<int64_t>(seconds);
    if (s >= 3600) return fmt::format("{}:{:02}:{:02}", s / 3600, s / 60 % 60, s % 60);
    return fmt::format("{:02}:{:02}", s / 60, s % 60);
}

}  // namespace

ProgressBar::ProgressBar(int64_t total, std::string label)
    : total_(std::max<int64_t>(total, 1)),
      label_(std::move(label)),
      enabled_(enabled()),
      start_(std::chrono::steady_clock::now()),
      last_draw_(start_ - std::chrono::seconds(1)) {}

ProgressBar::~ProgressBar() {
    if (enabled_ && !finished_) std::fputc('\n', stderr);
}

bool ProgressBar::enabled() { return isatty(fileno(stderr)) && !std::getenv("PUMETA_NO_PROGRESS"); }

void ProgressBar::update(int64_t done, const std::string& status) {
    done_ = done;
    if (!enabled_) return;
    auto now = std::chrono::steady_clock::now();
    if (now - last_draw_ < std::chrono::milliseconds(100) && done_ < total_) return;
    last_draw_ = now;
    draw(status);
}

void ProgressBar::finish(const std::string& status) {
    if (!enabled_ || finished_) return;
    done_ = total_;
    draw(status);
    std::fputc('\n', stderr);
    finished_ = true;
}

void ProgressBar::draw(const std::string& status) {
    constexpr int kWidth = 30;
    double fraction = std::min(1.0, static_cast<double>(done_) / total_);
    int filled = static_cast<int>(fraction * kWidth);
    double elapsed =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start_).count();
    double eta = fraction > 0 ? elapsed * (1 - fraction) / fraction : -1;
    double rate = elapsed > 0 ? done_ / elapsed : 0;
    std::string bar(filled, '#');
    bar.resize(kWidth, '-');
    std::fprintf(stderr, "\r\033[K%s [%s] %lld/%lld %s<%s %.1f/s %s", label_.c_str(), bar.c_str(),
                 static_cast<long long>(done_), static_cast<long long>(total_),
                 format_duration(elapsed).c_str(), format_duration(eta).c_str(), rate,
                 status.c_str());
    std::fflush(stderr);
}

}  // namespace pumeta
