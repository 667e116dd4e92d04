#include "core/integrator.h"

#include <algorithm>

#include "core/error.h"

namespace obscura {

IntegratorRegistry& IntegratorRegistry::instance() {
  static IntegratorRegistry r;
  return r;
}

void IntegratorRegistry::add(IntegratorDescriptor d) {
  for (const auto& e : all_)
    if (e.name == d.name) throw Error("integrator '" + d.name + "' is registered twice");
  all_.push_back(std::move(d));
  std::sort(all_.begin(), all_.end(), [](const auto& a, const auto& b) { return a.name < b.name; });
}

const IntegratorDescriptor& IntegratorRegistry::find(const std::string& name) const {
  for (const auto& e : all_)
    if (e.name == name) return e;
  std::string known;
  for (const auto& e : all_) known += (known.empty() ? "" : ", ") + e.name;
  throw Error("unknown integrator '" + name + "' (available: " + known + ")");
}

}  // namespace obscura
