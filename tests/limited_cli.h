// The CLI run under an address-space limit, with its peak RSS: a refusal
// that must come before an allocation is shown by a limit below the
// allocation, or by the RSS (issue #37's memory bombs).
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "tests/support.h"

namespace obscura::test {

// runCli under RLIMIT_AS = `addressSpaceBytes` (0: no limit), also
// returning the child's peak resident set in bytes (wait4's ru_maxrss).
struct LimitedCliResult : CliResult {
  uint64_t peakRssBytes = 0;
};
LimitedCliResult runCliLimited(const std::vector<std::string>& args, const std::string& stderrPath,
                               uint64_t addressSpaceBytes);

}  // namespace obscura::test
