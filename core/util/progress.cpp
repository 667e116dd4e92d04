#include "core/util/progress.h"

#include <unistd.h>

#include <cmath>
#include <cstdio>

namespace obscura {

std::string formatDuration(double s) {
  char buf[32];
  if (!std::isfinite(s) || s < 0) return "--:--";
  const long t = long(s + 0.5);
  if (t >= 3600)
    std::snprintf(buf, sizeof buf, "%ld:%02ld:%02ld", t / 3600, (t / 60) % 60, t % 60);
  else
    std::snprintf(buf, sizeof buf, "%02ld:%02ld", t / 60, t % 60);
  return buf;
}

Progress::Progress(std::string label, uint64_t total, bool enabled)
    : label_(std::move(label)), total_(total ? total : 1), enabled_(enabled), tty_(isatty(STDERR_FILENO)) {
  start_ = lastPrint_ = std::chrono::steady_clock::now();
  if (enabled_) print(0, false);
}

Progress::~Progress() { finish(); }

void Progress::advance(uint64_t amount) {
  const uint64_t done = done_.fetch_add(amount) + amount;
  if (!enabled_) return;
  std::unique_lock lock(mutex_, std::try_to_lock);
  if (!lock.owns_lock()) return;  // someone else is printing; skip this update
  print(done, false);
}

void Progress::setTotal(uint64_t total) { total_.store(total ? total : 1); }

void Progress::finish() {
  if (!enabled_ || finished_) return;
  std::lock_guard lock(mutex_);
  print(done_.load(), true);
  finished_ = true;
}

void Progress::print(uint64_t done, bool final) {
  const auto now = std::chrono::steady_clock::now();
  const double elapsed = std::chrono::duration<double>(now - start_).count();
  const double frac = std::min(1.0, double(done) / double(total_.load()));
  const double eta = frac > 0 ? elapsed * (1.0 - frac) / frac : NAN;
  if (tty_) {
    if (!final && done != 0 && now - lastPrint_ < std::chrono::milliseconds(200)) return;
    lastPrint_ = now;
    const int width = 30, filled = int(frac * width);
    std::string bar(size_t(filled), '#');
    bar.resize(width, '.');
    std::fprintf(stderr, "\r%s [%s] %5.1f%%  %s elapsed, ETA %s ", label_.c_str(), bar.c_str(), 100.0 * frac,
                 formatDuration(elapsed).c_str(), final ? "00:00" : formatDuration(eta).c_str());
    if (final) std::fputc('\n', stderr);
    std::fflush(stderr);
  } else {
    const int decile = int(frac * 10.0);
    if (!final && (decile <= lastDecile_ || now - lastPrint_ < std::chrono::seconds(2))) return;
    if (final && decile <= lastDecile_ && lastDecile_ >= 10) return;
    lastDecile_ = decile;
    lastPrint_ = now;
    std::fprintf(stderr, "%s: %5.1f%%  %s elapsed, ETA %s\n", label_.c_str(), 100.0 * frac,
                 formatDuration(elapsed).c_str(), final ? "00:00" : formatDuration(eta).c_str());
    std::fflush(stderr);
  }
}

}  // namespace obscura
