// Errors and warnings reported to the user.
//
// Every failure a user can cause (bad file, bad field, bad value) is thrown
// as obscura::Error with a message that names the file and the field; the CLI
// prints it on one line and exits non-zero.
#pragma once

#include <functional>
#include <mutex>
#include <set>
#include <stdexcept>
#include <string>

namespace obscura {

// `text` as one printable line: line breaks and tabs become spaces, other
// control bytes and bytes that are not UTF-8 become \xNN. Messages quote
// the user's files (a JSON parser's excerpt, a name), which may hold anything.
std::string printable(const std::string& text);

// The message is made printable (above), so every error line is.
class Error : public std::runtime_error {
 public:
  explicit Error(const std::string& message) : std::runtime_error(printable(message)) {}
  explicit Error(const char* message) : Error(std::string(message)) {}
};

// Warnings go through one sink so the CLI can print them and tests can
// collect them. warnOnce() suppresses repeats of the same text. Messages
// are made printable as errors are.
class Log {
 public:
  using Sink = std::function<void(const std::string&)>;
  static void setWarningSink(Sink sink);
  static void warn(const std::string& message);
  static void warnOnce(const std::string& message);
  static void resetOnce();
};

}  // namespace obscura
