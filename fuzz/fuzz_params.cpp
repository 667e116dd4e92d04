// libFuzzer target: integrator parameters as `-p key=value` gives them. The
// first line names the integrator (one of the registry's), each further
// line is one assignment. Invariants checked beyond "only obscura::Error":
// every value the set reports (ParamSet::values, what the EXR header
// records) parses back to itself, and the integrator is created from it.
#include <cstdlib>
#include <cstdio>

#include <obscura/error.h>
#include <obscura/params.h>
#include "fuzz/fuzz_common.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  using namespace obscura;
  const std::string text(reinterpret_cast<const char*>(data), size);
  std::vector<std::string> lines;
  size_t start = 0;
  for (size_t i = 0; i <= text.size(); ++i)
    if (i == text.size() || text[i] == '\n') lines.push_back(text.substr(start, i - start)), start = i + 1;
  const IntegratorDescriptor* d = nullptr;
  fuzz::expectOnlyErrors([&] { d = &IntegratorRegistry::instance().find(lines[0]); });
  if (!d) return 0;
  ParamSet p(d->params, d->name);
  bool fileParam = false;
  for (size_t i = 1; i < lines.size(); ++i)
    fuzz::expectOnlyErrors([&] {
      p.setAssignment(lines[i]);
      // A file parameter (containment's map) would read whatever path the
      // input names: the integrator is not created then.
      for (const ParamSpec& s : d->params)
        if (s.type == ParamType::String && lines[i].rfind(s.name + "=", 0) == 0) fileParam = true;
    });
  // Round trip: the text of each value parses back to the same text.
  ParamSet q(d->params, d->name);
  for (const auto& [key, value] : p.values()) q.set(key, value);
  if (q.values() != p.values()) {
    std::fprintf(stderr, "fuzz: parameter values do not round-trip\n");
    std::abort();
  }
  if (!fileParam) fuzz::expectOnlyErrors([&] {
      (void)d->needs(p);
      (void)d->create(p);
    });
  return 0;
}
