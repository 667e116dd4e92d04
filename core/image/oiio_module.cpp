#include "core/image/oiio_module.h"

#include <dlfcn.h>

#include <filesystem>
#include <mutex>

#include <obscura/error.h>

namespace obscura {

const OiioModule& oiioModule(const std::string& file) {
  static std::once_flag once;
  static const OiioModule* module = nullptr;
  static std::string failure;
  std::call_once(once, [] {
    // Next to this library (the build directory, or the installed libdir),
    // so the module found is the one built with it.
    Dl_info self{};
    std::string path = "libobscura_oiio.so";
    if (dladdr(reinterpret_cast<const void*>(&oiioModule), &self) && self.dli_fname)
      path = (std::filesystem::path(self.dli_fname).parent_path() / "libobscura_oiio.so").string();
    void* handle = dlopen(path.c_str(), RTLD_NOW | RTLD_LOCAL);
    if (!handle) {
      const char* e = dlerror();
      failure = e ? e : path + ": cannot load";
      return;
    }
    using Entry = const OiioModule* (*)();
    const auto entry = reinterpret_cast<Entry>(dlsym(handle, "obscura_oiio_module"));
    const OiioModule* m = entry ? entry() : nullptr;
    if (!m || m->abi != kOiioModuleAbi) {
      failure = path + ": not the module built with this libobscura (rebuild or reinstall obscura)";
      return;  // left loaded: dlclose of a library whose code may have run is not worth the risk
    }
    module = m;
  });
  if (!module) throw Error(file + ": reading this file needs OpenImageIO, through libobscura_oiio.so: " + failure);
  return *module;
}

}  // namespace obscura
