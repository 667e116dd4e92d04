#include "core/plugin.h"

#include <dlfcn.h>

#include <algorithm>
#include <cstdlib>
#include <filesystem>
#include <set>

#include "core/error.h"

namespace obscura {
namespace {

using RegisterFn = void (*)(IntegratorRegistry*, const char*);

// Checks the entry point of an opened module and registers its integrators.
// Exceptions from the module's code (a descriptor that throws, a duplicate
// name) propagate as obscura::Error naming the module.
void registerModule(void* handle, const std::string& origin, IntegratorRegistry& registry, bool required) {
  dlerror();
  const auto* abi = static_cast<const uint32_t*>(dlsym(handle, "obscura_plugin_abi_version"));
  if (!abi) {
    if (!required) return;
    throw Error(origin + ": not an Obscura plugin (no obscura_plugin_abi_version symbol; use OBSCURA_PLUGIN_ENTRY)");
  }
  if (*abi != OBSCURA_PLUGIN_ABI_VERSION)
    throw Error(origin + ": plugin ABI version " + std::to_string(*abi) + " does not match this obscura's " +
                std::to_string(OBSCURA_PLUGIN_ABI_VERSION) + "; rebuild the plugin against this version");
  auto reg = reinterpret_cast<RegisterFn>(dlsym(handle, "obscura_plugin_register"));
  if (!reg) throw Error(origin + ": plugin has no obscura_plugin_register symbol");
  try {
    reg(&registry, origin.c_str());
  } catch (const Error&) {
    throw;
  } catch (const std::exception& e) {
    throw Error(origin + ": plugin registration failed: " + e.what());
  }
}

std::set<std::string>& loadedPaths() {
  static std::set<std::string> s;
  return s;
}

}  // namespace

void loadBuiltinPlugins(IntegratorRegistry& registry) {
  // The program's own symbols: the built-in integrators (integrators/) are a
  // plugin linked into the executable, exporting the same entry point.
  void* self = dlopen(nullptr, RTLD_NOW);
  if (!self) return;
  registerModule(self, "built-in", registry, false);
}

void loadPlugin(const std::string& path) {
  std::error_code ec;
  if (!std::filesystem::exists(path, ec)) throw Error(path + ": cannot load plugin: no such file");
  const std::string canonical = std::filesystem::canonical(path, ec).string();
  if (!ec && loadedPaths().count(canonical)) return;  // the same library twice is one plugin
  IntegratorRegistry& registry = IntegratorRegistry::instance();
  // RTLD_LOCAL: the plugin's own obscura_plugin_* symbols stay private to it.
  void* handle = dlopen(path.find('/') == std::string::npos ? ("./" + path).c_str() : path.c_str(),
                        RTLD_NOW | RTLD_LOCAL);
  if (!handle) {
    const char* e = dlerror();
    throw Error(path + ": cannot load plugin: " + (e ? e : "unknown error"));
  }
  // A failed plugin stays mapped (its static objects may be referenced by a
  // partially built descriptor); plugins are few and small.
  registerModule(handle, path, registry, true);
  if (!ec) loadedPaths().insert(canonical);
}

void loadPluginsFromEnvironment() {
  const char* env = std::getenv("OBSCURA_PLUGIN_PATH");
  if (!env || !*env) return;
  std::string list(env);
  size_t start = 0;
  while (start <= list.size()) {
    const size_t end = std::min(list.find(':', start), list.size());
    const std::string entry = list.substr(start, end - start);
    start = end + 1;
    if (entry.empty()) continue;
    std::error_code ec;
    if (std::filesystem::is_directory(entry, ec)) {
      std::vector<std::string> files;
      for (const auto& f : std::filesystem::directory_iterator(entry, ec))
        if (f.path().extension() == ".so") files.push_back(f.path().string());
      std::sort(files.begin(), files.end());
      for (const auto& f : files) loadPlugin(f);
    } else {
      loadPlugin(entry);
    }
  }
}

}  // namespace obscura
