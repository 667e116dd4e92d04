// Integrator plugins: the one entry point built-in and third-party
// integrators share, and the loader that checks it.
//
// A module (the obscura program itself for the built-ins, or a shared
// library) lists its integrators with OBSCURA_REGISTER_INTEGRATOR(fn) - fn
// returns an IntegratorDescriptor - and exports them once with
// OBSCURA_PLUGIN_ENTRY("name"). That defines two C symbols:
//   obscura_plugin_abi_version  (data: OBSCURA_PLUGIN_ABI_VERSION at build time)
//   obscura_plugin_register     (function: adds the module's integrators)
// The loader reads the version from the library FILE (its ELF dynamic symbol
// table) before dlopen - dlopen runs a library's static constructors, so a
// check after it would come too late - and refuses a mismatch with a
// message; once loaded, dlsym checks the version again. A file that is not
// an ELF shared object, a library without the symbols, one that fails to
// load, or one whose registration throws gives an obscura::Error, never a
// crash. See docs/plugins.md.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include <obscura/integrator.h>

// The plugin ABI version: the one definition. Bumped whenever a header of
// include/obscura/ changes in a way that breaks binary compatibility (class
// layouts, virtual functions, inline code). The loader compares it, the
// installed CMake package reads it from this line (obscura_PLUGIN_ABI_VERSION),
// and docs/plugins.md "ABI history" lists every version (a test checks that
// the history reaches this one).
#define OBSCURA_PLUGIN_ABI_VERSION 12u

namespace obscura {

namespace detail {
using DescriptorFn = IntegratorDescriptor (*)();
// One list per module (hidden visibility: each shared library and the
// program get their own), filled by static initializers that only append
// function pointers. They run when the library is loaded, which happens only
// after its ABI version has been read from the file and matched.
__attribute__((visibility("hidden"))) inline std::vector<DescriptorFn>& moduleIntegrators() {
  static std::vector<DescriptorFn> list;
  return list;
}
}  // namespace detail

}  // namespace obscura

#define OBSCURA_REGISTER_INTEGRATOR(fn)                                            \
  namespace {                                                                     \
  [[maybe_unused]] const bool obscura_registered_##fn =                           \
      (::obscura::detail::moduleIntegrators().push_back(&fn), true);              \
  }

// Exactly once per module, at global scope.
#define OBSCURA_PLUGIN_ENTRY(pluginName)                                          \
  extern "C" __attribute__((visibility("default"))) const uint32_t               \
      obscura_plugin_abi_version = OBSCURA_PLUGIN_ABI_VERSION;                    \
  extern "C" __attribute__((visibility("default"))) const char                   \
      obscura_plugin_name[] = pluginName;                                         \
  extern "C" __attribute__((visibility("default"))) void obscura_plugin_register( \
      ::obscura::IntegratorRegistry* registry, const char* origin) {              \
    for (auto fn : ::obscura::detail::moduleIntegrators()) registry->add(fn(), origin); \
  }
