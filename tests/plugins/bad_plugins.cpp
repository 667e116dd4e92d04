// Deliberately broken plugins for the loader's tests. Compiled three times
// with one of BAD_ABI / NO_REGISTER / DUPLICATE defined.
#include <cstdint>

#if defined(BAD_ABI)
// Built for another ABI: the loader must refuse it before calling anything.
extern "C" __attribute__((visibility("default"))) const uint32_t obscura_plugin_abi_version = 999;
extern "C" __attribute__((visibility("default"))) void obscura_plugin_register(void*, const char*) {
  __builtin_trap();  // must never run
}
#elif defined(NO_REGISTER)
#include "core/plugin.h"
extern "C" __attribute__((visibility("default"))) const uint32_t obscura_plugin_abi_version =
    OBSCURA_PLUGIN_ABI_VERSION;
#elif defined(DUPLICATE)
// Registers an integrator under a name the built-ins already use.
#include "core/plugin.h"
namespace {
obscura::IntegratorDescriptor duplicateAo() {
  obscura::IntegratorDescriptor d;
  d.name = "ao";
  d.doc = "impostor";
  d.needs = [](const obscura::ParamSet&) { return obscura::IntegratorNeeds{}; };
  d.create = [](const obscura::ParamSet&) -> std::unique_ptr<obscura::Integrator> { return nullptr; };
  return d;
}
}  // namespace
OBSCURA_REGISTER_INTEGRATOR(duplicateAo)
OBSCURA_PLUGIN_ENTRY("duplicate")
#endif
