// Progress on stderr: a bar with ETA when stderr is a terminal, a line every
// 10 % (at most every few seconds) otherwise. Thread-safe; the render calls
// advance() once per finished tile, never from the hot loop.
#pragma once

#include <atomic>
#include <chrono>
#include <mutex>
#include <string>

namespace obscura {

class Progress {
 public:
  Progress(std::string label, uint64_t total, bool enabled);
  ~Progress();
  void advance(uint64_t amount);
  // A new total, when the work turns out to be more or less than first
  // thought (an adaptive render's forecast, revised each round); the bar
  // and the ETA follow it. Not from the hot loop.
  void setTotal(uint64_t total);
  uint64_t done() const { return done_.load(); }
  void finish();

 private:
  void print(uint64_t done, bool final);
  std::string label_;
  std::atomic<uint64_t> total_;
  bool enabled_, tty_;
  std::atomic<uint64_t> done_{0};
  std::mutex mutex_;
  std::chrono::steady_clock::time_point start_, lastPrint_;
  int lastDecile_ = -1;
  bool finished_ = false;
};

std::string formatDuration(double seconds);

}  // namespace obscura
