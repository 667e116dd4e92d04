#include "app/interrupt.h"

#include <unistd.h>

#include <csignal>
#include <cstring>

namespace obscura::interrupt {
namespace {

std::atomic<bool> gFlag{false};
std::atomic<bool> gPolling{false};
// The message as one NUL-terminated line ending in '\n'. setMessage never
// frees an old one: the handler may be reading it on another thread (a few
// bytes per command, set once or twice, or once per frame of a sequence).
std::atomic<const char*> gMessage{"obscura: interrupted\n"};
std::atomic<char*> gBlocks{nullptr};  // the newest block setMessage allocated
static_assert(std::atomic<bool>::is_always_lock_free && std::atomic<const char*>::is_always_lock_free,
              "the signal handler needs lock-free atomics");

extern "C" void onSignal(int) {
  gFlag.store(true);
  if (gPolling.load()) return;
  const char* m = gMessage.load();
  size_t n = 0;
  while (m[n] != '\0') ++n;
  while (n > 0) {  // stderr may take it in pieces
    const ssize_t w = ::write(STDERR_FILENO, m, n);
    if (w <= 0) break;
    m += w, n -= size_t(w);
  }
  ::_exit(130);
}

}  // namespace

void install() {
  struct sigaction sa;
  std::memset(&sa, 0, sizeof sa);
  sa.sa_handler = onSignal;
  sigemptyset(&sa.sa_mask);
  sa.sa_flags = SA_RESTART;  // polled phases keep running until they check the flag
  sigaction(SIGINT, &sa, nullptr);
  sigaction(SIGTERM, &sa, nullptr);
}

void setMessage(const std::string& line) {
  // Never freed (see gMessage). A command may set several (a sequence of
  // frames names each frame's output), so each block starts with the
  // address of the one before: all stay reachable from gBlocks, none is a
  // leak to LeakSanitizer.
  char* block = new char[sizeof(char*) + line.size() + 2];
  char* const previous = gBlocks.load();
  std::memcpy(block, &previous, sizeof previous);
  gBlocks.store(block);
  char* copy = block + sizeof(char*);
  std::memcpy(copy, line.data(), line.size());
  copy[line.size()] = '\n';
  copy[line.size() + 1] = '\0';
  gMessage.store(copy);
}

void startPolling() { gPolling.store(true); }

const std::atomic<bool>* flag() { return &gFlag; }

}  // namespace obscura::interrupt
