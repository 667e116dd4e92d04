#include "core/render/plugin_loader.h"
#include <obscura/plugin.h>

#include <dlfcn.h>
#include <elf.h>

#include <algorithm>
#include <bit>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <set>

#include <obscura/error.h>

namespace obscura {
namespace {

using RegisterFn = void (*)(IntegratorRegistry*, const char*);

constexpr const char* kAbiSymbol = "obscura_plugin_abi_version";

std::string noAbiSymbol(const std::string& origin) {
  return origin + ": not an Obscura plugin (no " + kAbiSymbol + " symbol; use OBSCURA_PLUGIN_ENTRY)";
}

std::string abiMismatch(const std::string& origin, uint32_t version) {
  return origin + ": plugin ABI version " + std::to_string(version) + ", this obscura needs " +
         std::to_string(OBSCURA_PLUGIN_ABI_VERSION) + "; rebuild the plugin against this version";
}

// Checks the entry point of an opened module and registers its integrators.
// Exceptions from the module's code (a descriptor that throws, a duplicate
// name) propagate as obscura::Error naming the module.
void registerModule(void* handle, const std::string& origin, IntegratorRegistry& registry, bool required) {
  dlerror();
  const auto* abi = static_cast<const uint32_t*>(dlsym(handle, kAbiSymbol));
  if (!abi) {
    if (!required) return;
    throw Error(noAbiSymbol(origin));
  }
  if (*abi != OBSCURA_PLUGIN_ABI_VERSION) throw Error(abiMismatch(origin, *abi));
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

// Bounds-checked reads from a file that may be truncated or malformed: every
// read names its range, and one outside the file is an error, never a read
// past the end.
class FileReader {
 public:
  explicit FileReader(const std::string& path) : in_(path, std::ios::binary) {
    if (!in_) throw Error(path + ": cannot load plugin: cannot open the file");
    in_.seekg(0, std::ios::end);
    size_ = uint64_t(std::max<std::streamoff>(0, in_.tellg()));
  }
  uint64_t size() const { return size_; }
  bool contains(uint64_t offset, uint64_t bytes) const { return offset <= size_ && bytes <= size_ - offset; }
  // Reads `bytes` at `offset`; false when the range is not inside the file.
  bool read(uint64_t offset, void* out, uint64_t bytes) {
    if (!contains(offset, bytes)) return false;
    in_.seekg(std::streamoff(offset));
    in_.read(static_cast<char*>(out), std::streamsize(bytes));
    return bool(in_);
  }
  template <class T>
  bool read(uint64_t offset, T& out) {
    return read(offset, &out, sizeof(T));
  }

 private:
  std::ifstream in_;
  uint64_t size_ = 0;
};

}  // namespace

// The ABI version is read from the file, not from the loaded library: dlopen
// runs the library's static constructors (and its dependencies') before
// dlsym could look at anything, so a plugin built for another ABI would run
// code compiled against headers that no longer match. Path: ELF header ->
// section headers -> the SHT_DYNSYM table and its string table (sh_link) ->
// the symbol's section (st_shndx) -> file offset = sh_offset + st_value -
// sh_addr. Only 64-bit ELF in the host's byte order is accepted (dlopen
// refuses anything else anyway).
uint32_t readPluginAbiVersion(const std::string& path) {
  FileReader f(path);
  const std::string notElf = path + ": not an ELF shared object";
  Elf64_Ehdr eh;
  if (!f.read(0, eh) || std::memcmp(eh.e_ident, ELFMAG, SELFMAG) != 0) throw Error(notElf);
  const unsigned char hostData = std::endian::native == std::endian::little ? ELFDATA2LSB : ELFDATA2MSB;
  if (eh.e_ident[EI_CLASS] != ELFCLASS64 || eh.e_ident[EI_DATA] != hostData)
    throw Error(notElf + " (not 64-bit ELF in this machine's byte order)");
  if (eh.e_type != ET_DYN) throw Error(notElf + " (ELF type " + std::to_string(eh.e_type) + ", not ET_DYN)");
  if (eh.e_shoff == 0 || eh.e_shentsize != sizeof(Elf64_Shdr))
    throw Error(notElf + " (no section header table)");
  // Extended numbering: e_shnum == 0 means the count is section 0's sh_size.
  uint64_t shnum = eh.e_shnum;
  Elf64_Shdr sh0;
  if (!f.read(eh.e_shoff, sh0)) throw Error(notElf + " (section header table outside the file)");
  if (shnum == 0) shnum = sh0.sh_size;
  if (shnum > f.size() / sizeof(Elf64_Shdr) || !f.contains(eh.e_shoff, shnum * sizeof(Elf64_Shdr)))
    throw Error(notElf + " (section header table outside the file)");
  const auto section = [&](uint64_t i) {
    Elf64_Shdr s;
    if (!f.read(eh.e_shoff + i * sizeof(Elf64_Shdr), s)) throw Error(notElf + " (bad section header)");
    return s;
  };
  for (uint64_t i = 0; i < shnum; ++i) {
    const Elf64_Shdr symtab = section(i);
    if (symtab.sh_type != SHT_DYNSYM) continue;
    if (symtab.sh_entsize != sizeof(Elf64_Sym) || symtab.sh_link >= shnum ||
        !f.contains(symtab.sh_offset, symtab.sh_size))
      throw Error(notElf + " (bad dynamic symbol table)");
    const Elf64_Shdr strtab = section(symtab.sh_link);
    if (!f.contains(strtab.sh_offset, strtab.sh_size)) throw Error(notElf + " (bad dynamic string table)");
    const uint64_t nameLen = std::strlen(kAbiSymbol) + 1;  // with its terminating NUL
    char name[32];
    static_assert(sizeof(name) >= sizeof("obscura_plugin_abi_version"));
    for (uint64_t k = 0; k < symtab.sh_size / sizeof(Elf64_Sym); ++k) {
      Elf64_Sym sym;
      if (!f.read(symtab.sh_offset + k * sizeof(Elf64_Sym), sym)) throw Error(notElf + " (bad symbol)");
      if (sym.st_name >= strtab.sh_size || strtab.sh_size - sym.st_name < nameLen) continue;
      if (!f.read(strtab.sh_offset + sym.st_name, name, nameLen) || std::memcmp(name, kAbiSymbol, nameLen) != 0)
        continue;
      if (sym.st_shndx == SHN_UNDEF) continue;  // a reference to another module's symbol, not a definition
      if (sym.st_size != sizeof(uint32_t))
        throw Error(path + ": " + kAbiSymbol + " is " + std::to_string(sym.st_size) + " bytes, not a uint32_t");
      if (sym.st_shndx >= shnum) throw Error(notElf + " (" + kAbiSymbol + " in no section)");
      const Elf64_Shdr data = section(sym.st_shndx);
      if (sym.st_value < data.sh_addr || data.sh_size < sizeof(uint32_t) ||
          sym.st_value - data.sh_addr > data.sh_size - sizeof(uint32_t))
        throw Error(notElf + " (" + kAbiSymbol + " outside its section)");
      if (data.sh_type == SHT_NOBITS) return 0;  // zero-initialized, not stored in the file
      if (!f.contains(data.sh_offset, data.sh_size)) throw Error(notElf + " (section outside the file)");
      uint32_t version = 0;
      if (!f.read(data.sh_offset + (sym.st_value - data.sh_addr), version))
        throw Error(notElf + " (" + kAbiSymbol + " outside the file)");
      return version;
    }
    throw Error(noAbiSymbol(path));
  }
  throw Error(noAbiSymbol(path));
}

namespace {

std::set<std::string>& loadedPaths() {
  static std::set<std::string> s;
  return s;
}

const void* gBuiltinAddress = nullptr;  // setBuiltinModule

}  // namespace

void setBuiltinModule(const void* addressInModule) { gBuiltinAddress = addressInModule; }

void loadBuiltinPlugins(IntegratorRegistry& registry) {
  if (gBuiltinAddress) {
    // A library already loaded: RTLD_NOLOAD only returns its handle.
    Dl_info info;
    void* module = dladdr(gBuiltinAddress, &info) && info.dli_fname ? dlopen(info.dli_fname, RTLD_NOW | RTLD_NOLOAD) : nullptr;
    if (!module) throw Error("the built-in integrators: cannot find the library that holds them");
    registerModule(module, "built-in", registry, true);
    return;
  }
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
  // The ABI is checked in the file before dlopen runs any of its code.
  const uint32_t version = readPluginAbiVersion(path);
  if (version != OBSCURA_PLUGIN_ABI_VERSION) throw Error(abiMismatch(path, version));
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
