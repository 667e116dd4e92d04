// An environment variable set for the processes a test starts while it
// lives (the tests' hooks: OBSCURA_TEST_CHECKPOINT_KILL, OBSCURA_TEST_COMMIT).
#pragma once

#include <cstdlib>
#include <string>
#include <utility>

namespace obscura::test {

struct ScopedEnv {
  std::string name;
  ScopedEnv(std::string n, const std::string& value) : name(std::move(n)) { setenv(name.c_str(), value.c_str(), 1); }
  ~ScopedEnv() { unsetenv(name.c_str()); }
  ScopedEnv(const ScopedEnv&) = delete;
  ScopedEnv& operator=(const ScopedEnv&) = delete;
};

}  // namespace obscura::test
