#include <obscura/error.h>

#include <cstdio>

namespace obscura {
namespace {
std::mutex gMutex;
Log::Sink gSink;
std::set<std::string> gSeen;
}  // namespace

std::string printable(const std::string& text) {
  std::string out;
  out.reserve(text.size());
  const auto hex = [&](unsigned char c) {
    static const char* digits = "0123456789abcdef";
    out.push_back('\\');
    out.push_back('x');
    out += digits[c >> 4];
    out += digits[c & 15];
  };
  for (size_t i = 0; i < text.size();) {
    const auto c = static_cast<unsigned char>(text[i]);
    if (c == '\n' || c == '\r' || c == '\t') {
      out += ' ';
      ++i;
    } else if (c < 0x20 || c == 0x7f) {
      hex(c);
      ++i;
    } else if (c < 0x80) {
      out += char(c);
      ++i;
    } else {
      // A UTF-8 sequence: lead byte, then 1-3 continuation bytes 10xxxxxx
      // (overlong and surrogate forms are not told apart: still printable).
      const size_t n = c >= 0xc2 && c <= 0xdf ? 2 : c >= 0xe0 && c <= 0xef ? 3 : c >= 0xf0 && c <= 0xf4 ? 4 : 0;
      bool ok = n > 0 && i + n <= text.size();
      for (size_t k = 1; ok && k < n; ++k) ok = (static_cast<unsigned char>(text[i + k]) & 0xc0) == 0x80;
      if (ok) {
        out.append(text, i, n);
        i += n;
      } else {
        hex(c);
        ++i;
      }
    }
  }
  while (!out.empty() && out.back() == ' ') out.pop_back();
  return out;
}

void Log::setWarningSink(Sink sink) {
  std::lock_guard lock(gMutex);
  gSink = std::move(sink);
}

void Log::warn(const std::string& text) {
  const std::string message = printable(text);
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
