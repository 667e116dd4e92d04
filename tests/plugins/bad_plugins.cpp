// Deliberately broken plugins for the loader's tests. Compiled once per kind
// with one of BAD_ABI / NO_REGISTER / DUPLICATE / CTOR_BAD_ABI /
// CTOR_GOOD_ABI defined.
#include <cstdint>

#if defined(CTOR_BAD_ABI) || defined(CTOR_GOOD_ABI)
// A static constructor with an observable effect: it creates the file named
// by OBSCURA_TEST_CTOR_MARKER. With a foreign ABI the loader must refuse the
// library before it is loaded, so the file never appears; with the right ABI
// (and no register function) the library is loaded, the file appears, and
// the load fails after it - the control that shows the marker works.
#include <cstdio>
#include <cstdlib>
namespace {
struct Marker {
  Marker() {
    if (const char* path = std::getenv("OBSCURA_TEST_CTOR_MARKER"))
      if (std::FILE* f = std::fopen(path, "w")) std::fclose(f);
  }
} marker;
}  // namespace
#if defined(CTOR_BAD_ABI)
extern "C" __attribute__((visibility("default"))) const uint32_t obscura_plugin_abi_version = 999;
#else
#include <obscura/plugin.h>
extern "C" __attribute__((visibility("default"))) const uint32_t obscura_plugin_abi_version =
    OBSCURA_PLUGIN_ABI_VERSION;
#endif
#endif

#if defined(BAD_ABI)
// Built for another ABI: the loader must refuse it before calling anything.
extern "C" __attribute__((visibility("default"))) const uint32_t obscura_plugin_abi_version = 999;
extern "C" __attribute__((visibility("default"))) void obscura_plugin_register(void*, const char*) {
  __builtin_trap();  // must never run
}
#elif defined(NO_REGISTER)
#include <obscura/plugin.h>
extern "C" __attribute__((visibility("default"))) const uint32_t obscura_plugin_abi_version =
    OBSCURA_PLUGIN_ABI_VERSION;
#elif defined(DUPLICATE)
// Registers an integrator under a name the built-ins already use.
#include <obscura/plugin.h>
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
