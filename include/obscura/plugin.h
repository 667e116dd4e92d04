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

#include "obscura/integrator.h"

// Bumped whenever a header a plugin compiles against changes in a way that
// breaks binary compatibility (class layouts, virtual functions, inline code
// that touches core data). 3: Primitive gained a name. 4: screen-space
// integrators (Integrator::screenSpace, IntegratorDescriptor::kind, core/render/gbuffer.h).
// 7: SurfaceHit::dir, IntegratorNeeds::roughness, Material's roughness.
// 8: SurfaceHit::time, RayBatch::push(..., const SurfaceHit&), Instance::motion.
#define OBSCURA_PLUGIN_ABI_VERSION 8u

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

// Loads the plugin library at `path` and registers its integrators.
// Throws obscura::Error naming the path on any failure.
void loadPlugin(const std::string& path);
// The value of obscura_plugin_abi_version as stored in the shared object
// file at `path`, read without loading it (bounds-checked: a truncated or
// malformed file gives an obscura::Error naming the path, "not an ELF shared
// object (...)" or "no obscura_plugin_abi_version symbol").
uint32_t readPluginAbiVersion(const std::string& path);
// Loads every plugin named by OBSCURA_PLUGIN_PATH: a ':'-separated list of
// plugin files or directories (every *.so in a directory, in name order).
void loadPluginsFromEnvironment();
// Registers the integrators compiled into the running program (through the
// same entry point as a plugin). Called once by IntegratorRegistry.
void loadBuiltinPlugins(IntegratorRegistry& registry);
// For a front end that is itself a shared library with the built-ins linked
// in (the Python module, loaded RTLD_LOCAL into python3, whose program has
// no entry point): the built-ins are taken from the library holding
// `addressInModule` instead. Call before the registry's first use.
void setBuiltinModule(const void* addressInModule);

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
