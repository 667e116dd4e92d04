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

class Error : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

// Warnings go through one sink so the CLI can print them and tests can
// collect them. warnOnce() suppresses repeats of the same text.
class Log {
 public:
  using Sink = std::function<void(const std::string&)>;
  static void setWarningSink(Sink sink);
  static void warn(const std::string& message);
  static void warnOnce(const std::string& message);
  static void resetOnce();
};

}  // namespace obscura
