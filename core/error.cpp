#include "core/error.h"

#include <cstdio>

namespace obscura {
namespace {
std::mutex gMutex;
Log::Sink gSink;
std::set<std::string> gSeen;
}  // namespace

void Log::setWarningSink(Sink sink) {
  std::lock_guard lock(gMutex);
  gSink = std::move(sink);
}

void Log::warn(const std::string& message) {
  std::lock_guard lock(gMutex);
  if (gSink)
    gSink(message);
  else
    std::fprintf(stderr, "obscura: warning: %s\n", message.c_str());
}

void Log::warnOnce(const std::string& message) {
  {
    std::lock_guard lock(gMutex);
    if (!gSeen.insert(message).second) return;
  }
  warn(message);
}

void Log::resetOnce() {
  std::lock_guard lock(gMutex);
  gSeen.clear();
}

}  // namespace obscura
