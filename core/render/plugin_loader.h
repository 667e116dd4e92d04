// The plugin loader: reads a library's ABI version from the file before
// loading it, loads it, and registers its integrators (the entry point is
// obscura/plugin.h). Not part of the SDK: front ends call it.
#pragma once

#include <cstdint>
#include <string>

#include <obscura/integrator.h>
#include <obscura/plugin.h>

namespace obscura {

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
