#include "core/load/gltf_document.h"

#include <nlohmann/json.hpp>
#include <tiny_gltf.h>

#include <algorithm>
#include <cerrno>
#include <climits>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <set>
#include <utility>

#include <obscura/error.h>
#include <obscura/params.h>
#include "core/util/input_file.h"
#include "core/util/option_names.h"

namespace obscura {
namespace {

namespace fs = std::filesystem;
using json = nlohmann::json;

Matrix4d identity4() { return {1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1}; }

Matrix4d mul(const Matrix4d& a, const Matrix4d& b) {
  Matrix4d r{};
  for (int c = 0; c < 4; ++c)
    for (int row = 0; row < 4; ++row) {
      double v = 0;
      for (int k = 0; k < 4; ++k) v += a[k * 4 + row] * b[c * 4 + k];
      r[c * 4 + row] = v;
    }
  return r;
}

std::string number(double v) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%g", v);
  return buf;
}

// Encoded image bytes handed over by tinygltf, decoded later (lazily).
bool keepImageBytes(tinygltf::Image* image, const int index, std::string*, std::string*, int, int,
                    const unsigned char* data, int size, void* user) {
  auto* store = static_cast<std::map<int, std::vector<unsigned char>>*>(user);
  (*store)[index].assign(data, data + size);
  image->width = image->height = 0;  // not decoded yet
  return true;
}

// --- the JSON types the decoding relies on ------------------------------------
//
// tinygltf skips a field of the wrong type without a word; the decoding
// would then take it as absent (a node's "mesh": "0" drops the mesh, a
// "matrix" of strings the transform). Each such field is refused instead:
// a render missing part of the scene looks plausible and is wrong, which is
// worse than an error that names the field.

enum class Kind { Index, Uint, Int, Number, Bool, String, Object, IndexArray, NumberArray, ObjectArray };

const char* expected(Kind k) {
  switch (k) {
    case Kind::Index: return "a non-negative integer";
    case Kind::Uint: return "a non-negative integer";
    case Kind::Int: return "an integer";
    case Kind::Number: return "a number";
    case Kind::Bool: return "a boolean";
    case Kind::String: return "a string";
    case Kind::Object: return "an object";
    case Kind::IndexArray: return "an array of non-negative integers";
    case Kind::NumberArray: return "an array of numbers";
    case Kind::ObjectArray: return "an array of objects";
  }
  return "?";
}

std::string got(const json& v) {
  switch (v.type()) {
    case json::value_t::null: return "null";
    case json::value_t::boolean: return "a boolean";
    case json::value_t::string: return "a string";
    case json::value_t::array: return "an array";
    case json::value_t::object: return "an object";
    case json::value_t::number_float: return "the number " + number(v.get<double>());
    case json::value_t::number_integer:
    case json::value_t::number_unsigned: return "the integer " + v.dump();
    default: return "a " + std::string(v.type_name());
  }
}

bool matches(const json& v, Kind k) {
  switch (k) {
    // An index must also fit tinygltf's int.
    case Kind::Index:
      if (v.is_number_unsigned()) return v.get<uint64_t>() <= uint64_t(INT_MAX);
      return v.is_number_integer() && v.get<int64_t>() >= 0 && v.get<int64_t>() <= INT_MAX;
    case Kind::Uint: return v.is_number_unsigned() || (v.is_number_integer() && v.get<int64_t>() >= 0);
    case Kind::Int: return v.is_number_integer() && v.get<int64_t>() >= INT_MIN && v.get<int64_t>() <= INT_MAX;
    case Kind::Number: return v.is_number();
    case Kind::Bool: return v.is_boolean();
    case Kind::String: return v.is_string();
    case Kind::Object: return v.is_object();
    case Kind::IndexArray:
      return v.is_array() && std::all_of(v.begin(), v.end(), [](const json& e) { return matches(e, Kind::Index); });
    case Kind::NumberArray: return v.is_array() && std::all_of(v.begin(), v.end(), [](const json& e) { return e.is_number(); });
    case Kind::ObjectArray: return v.is_array() && std::all_of(v.begin(), v.end(), [](const json& e) { return e.is_object(); });
  }
  return false;
}

struct Rule {
  const char* key;
  Kind kind;
};

class JsonChecker {
 public:
  explicit JsonChecker(const GltfDocument& doc) : doc_(doc) {}

  // obj.key, when present, is of `kind`.
  void field(const json& obj, const std::string& where, const Rule& r) const {
    auto it = obj.find(r.key);
    if (it == obj.end()) return;
    const std::string f = where + "." + r.key;
    if (matches(*it, r.kind)) return;
    // Name the element of an array that is wrong.
    if (it->is_array() && (r.kind == Kind::IndexArray || r.kind == Kind::NumberArray || r.kind == Kind::ObjectArray)) {
      const Kind each = r.kind == Kind::IndexArray ? Kind::Index : r.kind == Kind::NumberArray ? Kind::Number : Kind::Object;
      for (size_t i = 0; i < it->size(); ++i)
        if (!matches((*it)[i], each))
          doc_.fail(f + "[" + std::to_string(i) + "]", std::string("expected ") + expected(each) + ", got " + got((*it)[i]));
    }
    doc_.fail(f, std::string("expected ") + expected(r.kind) + ", got " + got(*it));
  }
  void fields(const json& obj, const std::string& where, std::initializer_list<Rule> rules) const {
    for (const Rule& r : rules) field(obj, where, r);
  }
  struct Length {
    const char* key;
    size_t n;
  };
  // obj.key, when present (an array: field() has checked), has exactly n elements.
  void lengths(const json& obj, const std::string& where, std::initializer_list<Length> rules) const {
    for (const Length& r : rules)
      if (auto it = obj.find(r.key); it != obj.end() && it->size() != r.n)
        doc_.fail(where + "." + r.key, "expected " + std::to_string(r.n) + " numbers, got " + std::to_string(it->size()));
  }
  // obj.key[i] (an array of objects) with the rules, each.
  template <class F>
  void each(const json& obj, const std::string& where, const char* key, F&& check) const {
    field(obj, where, {key, Kind::ObjectArray});
    auto it = obj.find(key);
    if (it == obj.end()) return;
    const std::string prefix = (where.empty() ? "" : where + ".") + key;
    for (size_t i = 0; i < it->size(); ++i) check((*it)[i], prefix + "[" + std::to_string(i) + "]");
  }

  // tinygltf reads an integer in extras or extensions into an int, wrapping
  // one beyond its range (an extras.obscura.subdivision.level of 4294967298
  // became 2), so such an integer is refused wherever it is, naming its path.
  // Recursive: the nesting is at most kMaxJsonDepth, checked before parsing.
  void extrasIntegers(const json& v, const std::string& path, bool inExtras) const {
    if (v.is_object()) {
      for (const auto& [key, e] : v.items())
        extrasIntegers(e, path.empty() ? key : path + "." + key, inExtras || key == "extras" || key == "extensions");
    } else if (v.is_array()) {
      for (size_t i = 0; i < v.size(); ++i) extrasIntegers(v[i], path + "[" + std::to_string(i) + "]", inExtras);
    } else if (inExtras && (v.is_number_unsigned() ? v.get<uint64_t>() > uint64_t(INT_MAX) : !matches(v, Kind::Int) && v.is_number_integer())) {
      doc_.fail(path, "the integer " + v.dump() + " is outside [" + std::to_string(INT_MIN) + ", " + std::to_string(INT_MAX) +
                          "], the range a glTF reader keeps");
    }
  }

  void document(const json& root) const {
    extrasIntegers(root, "", false);
    // Top-level arrays are named without a leading dot.
    const auto arr = [&](const char* key, auto&& check) {
      auto it = root.find(key);
      if (it == root.end()) return;
      if (!matches(*it, Kind::ObjectArray)) {
        if (it->is_array())
          for (size_t i = 0; i < it->size(); ++i)
            if (!(*it)[i].is_object())
              doc_.fail(std::string(key) + "[" + std::to_string(i) + "]", "expected an object, got " + got((*it)[i]));
        doc_.fail(key, "expected an array of objects, got " + got(*it));
      }
      for (size_t i = 0; i < it->size(); ++i) check((*it)[i], std::string(key) + "[" + std::to_string(i) + "]");
    };
    if (auto s = root.find("scene"); s != root.end() && !matches(*s, Kind::Index))
      doc_.fail("scene", std::string("expected ") + expected(Kind::Index) + ", got " + got(*s));
    arr("scenes", [&](const json& s, const std::string& w) { fields(s, w, {{"nodes", Kind::IndexArray}}); });
    arr("nodes", [&](const json& n, const std::string& w) {
      fields(n, w, {{"mesh", Kind::Index}, {"camera", Kind::Index}, {"skin", Kind::Index}, {"children", Kind::IndexArray},
                    {"matrix", Kind::NumberArray}, {"translation", Kind::NumberArray}, {"rotation", Kind::NumberArray},
                    {"scale", Kind::NumberArray}, {"name", Kind::String}});
      // tinygltf keeps an array of the wrong length and the decoding took it
      // as absent: a matrix of 15 numbers placed the node at the identity.
      lengths(n, w, {{"matrix", 16}, {"translation", 3}, {"rotation", 4}, {"scale", 3}});
      // glTF 2.0 §5.25: a node has a matrix or TRS properties, not both; the
      // decoding would take the matrix and drop the rest without a word.
      if (n.contains("matrix"))
        for (const char* trs : {"translation", "rotation", "scale"})
          if (n.contains(trs))
            doc_.fail(w + "." + trs, std::string("a node with a matrix must not have a ") + trs + " (glTF 2.0: one or the other)");
    });
    arr("meshes", [&](const json& m, const std::string& w) {
      fields(m, w, {{"name", Kind::String}});
      each(m, w, "primitives", [&](const json& p, const std::string& pw) {
        fields(p, pw, {{"attributes", Kind::Object}, {"indices", Kind::Index}, {"mode", Kind::Int}, {"material", Kind::Index}});
        if (auto a = p.find("attributes"); a != p.end())
          for (const auto& [name, value] : a->items())
            if (!matches(value, Kind::Index))
              doc_.fail(pw + ".attributes." + name, std::string("expected ") + expected(Kind::Index) + ", got " + got(value));
      });
    });
    arr("accessors", [&](const json& a, const std::string& w) {
      fields(a, w, {{"bufferView", Kind::Index}, {"byteOffset", Kind::Uint}, {"componentType", Kind::Int}, {"count", Kind::Uint},
                    {"type", Kind::String}, {"normalized", Kind::Bool}, {"sparse", Kind::Object}});
    });
    arr("bufferViews", [&](const json& v, const std::string& w) {
      fields(v, w, {{"buffer", Kind::Index}, {"byteOffset", Kind::Uint}, {"byteLength", Kind::Uint}, {"byteStride", Kind::Uint}});
      // A view must lie inside its buffer's declared length: tinygltf hands
      // an image's view to the image loader by the view's own length (an
      // overread, found by fuzz/obscura_fuzz_gltf).
      const auto bi = v.find("buffer"), bufs = root.find("buffers");
      if (bi == v.end() || bufs == root.end() || !bufs->is_array() || bi->get<uint64_t>() >= bufs->size()) return;
      const json& b = (*bufs)[size_t(bi->get<uint64_t>())];
      const auto bl = b.is_object() ? b.find("byteLength") : b.end();
      const auto vl = v.find("byteLength"), vo = v.find("byteOffset");
      if (!b.is_object() || bl == b.end() || !bl->is_number_unsigned() || vl == v.end()) return;
      const uint64_t size = bl->get<uint64_t>(), length = vl->get<uint64_t>();
      const uint64_t offset = vo == v.end() ? 0 : vo->get<uint64_t>();
      if (offset > size || length > size - offset)
        doc_.fail(w, "byteOffset " + std::to_string(offset) + " + byteLength " + std::to_string(length) +
                         " runs past buffers[" + std::to_string(bi->get<uint64_t>()) + "].byteLength " + std::to_string(size));
    });
    arr("buffers", [&](const json& b, const std::string& w) { fields(b, w, {{"uri", Kind::String}, {"byteLength", Kind::Uint}}); });
    arr("materials", [&](const json& m, const std::string& w) {
      fields(m, w, {{"name", Kind::String}, {"pbrMetallicRoughness", Kind::Object}, {"alphaMode", Kind::String},
                    {"alphaCutoff", Kind::Number}, {"emissiveFactor", Kind::NumberArray}, {"normalTexture", Kind::Object}});
      lengths(m, w, {{"emissiveFactor", 3}});
      // A textureInfo and its KHR_texture_transform.
      const auto textureInfo = [&](const json& t, const std::string& tw, bool normal) {
        fields(t, tw, {{"index", Kind::Index}, {"texCoord", Kind::Uint}, {"extensions", Kind::Object}});
        if (normal) field(t, tw, {"scale", Kind::Number});
        if (auto e = t.find("extensions"); e != t.end())
          if (auto x = e->find("KHR_texture_transform"); x != e->end()) {
            const std::string xw = tw + ".extensions.KHR_texture_transform";
            if (!x->is_object()) doc_.fail(xw, "expected an object, got " + got(*x));
            fields(*x, xw, {{"offset", Kind::NumberArray}, {"rotation", Kind::Number}, {"scale", Kind::NumberArray},
                            {"texCoord", Kind::Uint}});
          }
      };
      if (auto t = m.find("normalTexture"); t != m.end()) textureInfo(*t, w + ".normalTexture", true);
      if (auto pbr = m.find("pbrMetallicRoughness"); pbr != m.end()) {
        const std::string pw = w + ".pbrMetallicRoughness";
        fields(*pbr, pw, {{"baseColorFactor", Kind::NumberArray}, {"baseColorTexture", Kind::Object},
                          {"roughnessFactor", Kind::Number}, {"metallicFactor", Kind::Number},
                          {"metallicRoughnessTexture", Kind::Object}});
        lengths(*pbr, pw, {{"baseColorFactor", 4}});
        for (const char* key : {"baseColorTexture", "metallicRoughnessTexture"})
          if (auto t = pbr->find(key); t != pbr->end()) textureInfo(*t, pw + "." + key, false);
      }
    });
    arr("textures", [&](const json& t, const std::string& w) { fields(t, w, {{"source", Kind::Index}, {"sampler", Kind::Index}}); });
    arr("images", [&](const json& i, const std::string& w) {
      fields(i, w, {{"uri", Kind::String}, {"bufferView", Kind::Index}, {"mimeType", Kind::String}});
    });
    arr("samplers", [&](const json& s, const std::string& w) { fields(s, w, {{"wrapS", Kind::Int}, {"wrapT", Kind::Int}}); });
    arr("animations", [&](const json& a, const std::string& w) {
      fields(a, w, {{"name", Kind::String}});
      each(a, w, "channels", [&](const json& c, const std::string& cw) {
        fields(c, cw, {{"sampler", Kind::Index}, {"target", Kind::Object}});
        if (auto t = c.find("target"); t != c.end()) fields(*t, cw + ".target", {{"node", Kind::Index}, {"path", Kind::String}});
      });
      each(a, w, "samplers", [&](const json& s, const std::string& sw) {
        fields(s, sw, {{"input", Kind::Index}, {"output", Kind::Index}, {"interpolation", Kind::String}});
      });
    });
    arr("cameras", [&](const json& c, const std::string& w) {
      fields(c, w, {{"type", Kind::String}, {"name", Kind::String}, {"perspective", Kind::Object}});
      if (auto p = c.find("perspective"); p != c.end())
        fields(*p, w + ".perspective", {{"yfov", Kind::Number}, {"znear", Kind::Number}, {"zfar", Kind::Number},
                                        {"aspectRatio", Kind::Number}});
    });
  }

 private:
  const GltfDocument& doc_;
};

// tinygltf's file access, replaced: it decodes a uri its own way (a "+" as a
// space, "%zz" as a NUL byte, so "%zz.bin" named the scene's directory) and
// then read whatever that named - a directory came back as a file of
// 2^63 bytes, "out of memory". Whatever tinygltf decoded, the read goes
// through here and refuses anything that is not a regular file; no shell
// expansion of the name either (tinygltf's default runs wordexp on it).
bool uriFileExists(const std::string& path, void*) {
  std::error_code ec;
  return fs::exists(path, ec);
}
std::string uriFilePath(const std::string& path, void*) { return path; }
bool readUriFile(std::vector<unsigned char>* out, std::string* err, const std::string& path, void*) {
  std::error_code ec;
  if (!fs::is_regular_file(path, ec)) {
    if (err) *err += "'" + path + "' is not a regular file" + (fs::is_directory(path, ec) ? " (a directory)" : "");
    return false;
  }
  std::ifstream in(path, std::ios::binary);
  const auto size = fs::file_size(path, ec);
  if (!in || ec) {
    if (err) *err += "cannot read '" + path + "': " + std::strerror(errno);
    return false;
  }
  out->resize(size_t(size));
  in.read(reinterpret_cast<char*>(out->data()), std::streamsize(out->size()));
  if (in.gcount() != std::streamsize(out->size())) {
    if (err) *err += "cannot read '" + path + "'";
    return false;
  }
  return true;
}
bool refuseWrite(std::string* err, const std::string&, const std::vector<unsigned char>&, void*) {
  if (err) *err += "writing is not supported";
  return false;
}

// A percent sign not followed by two hex digits (RFC 3986 allows no other).
size_t malformedEscape(const std::string& uri) {
  for (size_t i = 0; i < uri.size(); ++i)
    if (uri[i] == '%' && !(i + 2 < uri.size() && std::isxdigit(static_cast<unsigned char>(uri[i + 1])) &&
                           std::isxdigit(static_cast<unsigned char>(uri[i + 2]))))
      return i;
  return std::string::npos;
}

bool isGlb(const std::vector<unsigned char>& bytes) { return bytes.size() >= 4 && std::memcmp(bytes.data(), "glTF", 4) == 0; }

// The JSON text: the whole file, or a .glb's first chunk (header: magic,
// version, length; chunk: length, type "JSON", data). A container tinygltf
// will refuse anyway is left to it ("").
std::string jsonText(const std::vector<unsigned char>& bytes) {
  std::string text;
  if (!isGlb(bytes)) {
    text.assign(bytes.begin(), bytes.end());
  } else if (bytes.size() >= 20) {
    uint32_t length = 0, type = 0;
    std::memcpy(&length, bytes.data() + 12, 4);
    std::memcpy(&type, bytes.data() + 16, 4);
    if (type == 0x4E4F534A && length <= bytes.size() - 20) text.assign(bytes.begin() + 20, bytes.begin() + 20 + length);
  }
  return text;
}

// The uri as a file name: percent-escapes decoded, as tinygltf reads it.
std::string decodeUri(const std::string& uri) {
  std::string out;
  for (size_t i = 0; i < uri.size(); ++i) {
    if (uri[i] == '%' && i + 2 < uri.size() && std::isxdigit(static_cast<unsigned char>(uri[i + 1])) &&
        std::isxdigit(static_cast<unsigned char>(uri[i + 2]))) {
      out += char(std::stoi(uri.substr(i + 1, 2), nullptr, 16));
      i += 2;
    } else {
      out += uri[i];
    }
  }
  return out;
}

// The deepest nesting of arrays and objects a scene's JSON may have.
// tinygltf turns JSON into its Values (extras, extensions) recursively, a
// stack frame or more a level: 30,000 nested arrays in `extras` overflowed
// the 8 MB main stack (SIGSEGV), and a thread's stack may be far smaller
// (512 KB on macOS, Python's and TBB's threads). The glTF schema itself
// needs fewer than 10 levels and DCC tools write flat extras; 512 leaves
// room for any real file while keeping the recursion well under 512 KB.
constexpr size_t kMaxJsonDepth = 512;

// The deepest nesting of [ and { in JSON text outside strings, and the byte
// offset where it is first reached: one pass, no recursion, no allocation.
std::pair<size_t, size_t> jsonDepth(const unsigned char* p, size_t n) {
  size_t depth = 0, deepest = 0, at = 0;
  bool inString = false;
  for (size_t i = 0; i < n; ++i) {
    const unsigned char c = p[i];
    if (inString) {
      if (c == '\\') ++i;  // the escaped character, whatever it is
      else if (c == '"') inString = false;
    } else if (c == '"') {
      inString = true;
    } else if (c == '[' || c == '{') {
      if (++depth > deepest) deepest = depth, at = i;
    } else if ((c == ']' || c == '}') && depth > 0) {
      --depth;
    }
  }
  return {deepest, at};
}

}  // namespace

struct GltfDocument::View {
  const unsigned char* data = nullptr;  // first element
  size_t stride = 0, count = 0;
  int componentType = 0, components = 0;
  bool normalized = false;
};

GltfDocument::GltfDocument(std::string path) : path_(std::move(path)), model_(std::make_unique<tinygltf::Model>()) {
  read();
  warnUnsupported();
  decodeMaterials();
  decodeNodes();
}

GltfDocument::~GltfDocument() = default;

void GltfDocument::fail(const std::string& field, const std::string& what) const {
  throw Error(path_ + ": " + field + ": " + what);
}

void GltfDocument::warn(const std::string& what) const { Log::warnOnce(path_ + ": " + what); }

void GltfDocument::read() {
  std::error_code ec;
  if (!fs::exists(path_, ec)) throw Error(path_ + ": cannot open scene: no such file");
  checkInputFile(path_);
  std::ifstream in(path_, std::ios::binary);
  if (!in) throw Error(path_ + ": cannot open scene: " + std::strerror(errno));
  // In one read when the size is known (a regular file): a byte-wise
  // istreambuf_iterator copy took ~10 ms of the default scene's start-up.
  std::vector<unsigned char> bytes;
  if (in.seekg(0, std::ios::end); in && in.tellg() >= 0) {
    bytes.resize(size_t(in.tellg()));
    in.seekg(0);
    in.read(reinterpret_cast<char*>(bytes.data()), std::streamsize(bytes.size()));
    if (in.gcount() != std::streamsize(bytes.size())) throw Error(path_ + ": cannot read scene: " + std::strerror(errno));
  } else {
    in.clear();
    in.seekg(0);
    bytes.assign(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
  }
  const bool binary = isGlb(bytes);
  std::string text = jsonText(bytes);
  // Refused before any parser sees it: the parsers recurse per level
  // (docs/scenes.md "What the loader refuses"). A .glb's JSON chunk is scanned whatever its
  // declared type or length (tinygltf decides those later).
  {
    const unsigned char* json0 = binary ? bytes.data() + std::min<size_t>(20, bytes.size())
                                        : reinterpret_cast<const unsigned char*>(text.data());
    const size_t jsonBytes = binary ? (text.empty() ? bytes.size() - std::min<size_t>(20, bytes.size()) : text.size())
                                    : text.size();
    const auto [deepest, at] = jsonDepth(json0, jsonBytes);
    if (deepest > kMaxJsonDepth)
      throw Error(path_ + ": the JSON nests " + std::to_string(deepest) + " arrays and objects deep (at byte " +
                  std::to_string(binary ? at + size_t(json0 - bytes.data()) : at) +
                  "); at most " + std::to_string(kMaxJsonDepth) + " levels are accepted");
  }
  const json root = json::parse(text, nullptr, /*allow_exceptions=*/false);
  if (root.is_object()) {  // anything else is not glTF, as tinygltf says below
    JsonChecker(*this).document(root);
    // Buffers and images outside the file: a uri naming something that is
    // not a regular file (a directory, a device) is refused here; tinygltf
    // would read a directory as a file of unknown size ("out of memory").
    const std::string base = fs::path(path_).parent_path().string();
    for (const char* array : {"buffers", "images"}) {
      auto it = root.find(array);
      if (it == root.end()) continue;
      for (size_t i = 0; i < it->size(); ++i) {
        auto uri = (*it)[i].find("uri");
        if (uri == (*it)[i].end() || uri->get<std::string>().rfind("data:", 0) == 0) continue;
        const std::string& text = uri->get<std::string>();
        if (const size_t at = malformedEscape(text); at != std::string::npos)
          fail(std::string(array) + "[" + std::to_string(i) + "].uri",
               "'" + text + "' has a malformed percent escape at character " + std::to_string(at) +
                   " (a '%' takes two hex digits: %20 for a space)");
        const std::string name = decodeUri(text);
        const fs::path file = fs::path(name).is_absolute() ? fs::path(name) : fs::path(base.empty() ? "." : base) / name;
        const std::string kind = name.empty() ? "a directory" : nonRegularKind(file.string());
        if (!kind.empty())
          fail(std::string(array) + "[" + std::to_string(i) + "].uri", "'" + uri->get<std::string>() + "' is not a file (" + kind + ")");
      }
    }
  }

  // Every chunk of a .glb must lie inside the file: tinygltf copies the
  // binary chunk by its declared length without checking it against the
  // file's end (found by fuzz/obscura_fuzz_gltf: an overread).
  if (binary && bytes.size() >= 12) {
    for (uint64_t at = 12; at < bytes.size();) {
      uint32_t length = 0;
      if (bytes.size() - at < 8) throw Error(path_ + ": not a valid glTF 2.0 file: a .glb chunk header is cut off");
      std::memcpy(&length, bytes.data() + at, 4);
      if (uint64_t(length) > bytes.size() - at - 8)
        throw Error(path_ + ": not a valid glTF 2.0 file: a .glb chunk of " + std::to_string(length) +
                    " bytes runs past the end of the file");
      at += 8 + uint64_t(length);
    }
  }

  tinygltf::TinyGLTF loader;
  loader.SetImageLoader(keepImageBytes, &imageBytes_);
  loader.SetFsCallbacks({uriFileExists, uriFilePath, readUriFile, refuseWrite, nullptr});
  std::string err, warning;
  const std::string baseDir = fs::path(path_).parent_path().string();
  const bool ok = binary ? loader.LoadBinaryFromMemory(model_.get(), &err, &warning, bytes.data(), unsigned(bytes.size()), baseDir)
                         : loader.LoadASCIIFromString(model_.get(), &err, &warning, text.data(), unsigned(text.size()), baseDir);
  if (!warning.empty()) warn(warning);
  if (!ok || !err.empty()) throw Error(path_ + ": not a valid glTF 2.0 file: " + (err.empty() ? "parse error" : err));
}

void GltfDocument::warnUnsupported() {
  // The extensions the decoding honours: quantized attributes are read as
  // any normalized or integer accessor (component()), texture transforms
  // are applied to every texture read (docs/scenes.md "Texture transforms"),
  // and an emission strength changes nothing an ambient pass computes.
  static const std::set<std::string> supported = {"KHR_materials_emissive_strength", "KHR_mesh_quantization",
                                                  "KHR_texture_transform"};
  for (const auto& e : model_->extensionsUsed)
    if (!supported.count(e)) warn("extension " + e + " is not supported (ignored)");
  // glTF 2.0 §3.12: a loader that does not support an extension listed in
  // extensionsRequired MUST fail to load the file; a render that ignored it
  // (a compressed mesh left out, a transform not applied) would look
  // plausible and be wrong.
  for (size_t i = 0; i < model_->extensionsRequired.size(); ++i) {
    const std::string& e = model_->extensionsRequired[i];
    if (supported.count(e)) continue;
    std::string all;
    for (const auto& k : supported) all += (all.empty() ? "" : ", ") + k;
    const bool compression = e == "KHR_draco_mesh_compression" || e == "EXT_meshopt_compression";
    fail("extensionsRequired[" + std::to_string(i) + "]",
         e + " is not supported" + (compression ? "; decompress the file first" : "") + " (supported: " + all + ")");
  }
  if (!model_->skins.empty()) warn("skins are not supported (meshes render in bind pose)");
  if (!model_->lights.empty()) warn("KHR_lights_punctual lights are ignored (the sky is the only light)");
}

void GltfDocument::decodeMaterials() {
  // One texture per image and colour space: a base colour is sRGB (in
  // textures_), a metallicRoughness image linear data (in dataTextures_), and
  // one image may serve as both.
  std::map<std::pair<int, bool>, int> imageToTexture;
  struct TextureUse {
    int index = -1;
    WrapMode wrapS = WrapMode::Repeat, wrapT = WrapMode::Repeat;
    UvTransform transform;
  };
  // The texture a material's textureInfo (its index, texCoord and
  // extensions, at `tfield`) refers to; index -1 when it is absent or on a
  // texture coordinate set other than 0 (warned). KHR_texture_transform's
  // texCoord, when present, overrides the textureInfo's (the extension's
  // rule).
  const auto textureUse = [&](int index, int texCoord, const tinygltf::ExtensionMap& extensions,
                              const std::string& tfield, bool srgb) {
    TextureUse use;
    if (index < 0) return use;
    if (size_t(index) >= model_->textures.size())
      fail(tfield + ".index", "texture " + std::to_string(index) + " does not exist");
    if (auto x = extensions.find("KHR_texture_transform"); x != extensions.end()) {
      const tinygltf::Value& e = x->second;
      const std::string xw = tfield + ".extensions.KHR_texture_transform";
      // The JSON checker has checked every type; the counts and finiteness here.
      const auto pair = [&](const char* key, double fallback, double out[2]) {
        out[0] = out[1] = fallback;
        if (!e.Has(key)) return;
        const tinygltf::Value& a = e.Get(key);
        if (!a.IsArray() || a.ArrayLen() != 2) fail(xw + "." + key, "expected 2 numbers");
        for (int k = 0; k < 2; ++k) {
          out[k] = a.Get(k).GetNumberAsDouble();
          if (!std::isfinite(out[k])) fail(xw + "." + key, "must be finite");
        }
      };
      double offset[2], scale[2];
      pair("offset", 0.0, offset);
      pair("scale", 1.0, scale);
      const double rotation = e.Has("rotation") ? e.Get("rotation").GetNumberAsDouble() : 0.0;
      if (!std::isfinite(rotation)) fail(xw + ".rotation", "must be finite");
      use.transform = UvTransform::fromKhr(offset[0], offset[1], rotation, scale[0], scale[1]);
      if (e.Has("texCoord")) texCoord = e.Get("texCoord").GetNumberAsInt();
    }
    if (texCoord != 0) {
      warn("textures on TEXCOORD_" + std::to_string(texCoord) + " are not supported (only TEXCOORD_0; texture ignored)");
      return TextureUse{};
    }
    for (const auto& [name, value] : extensions)
      if (name != "KHR_texture_transform") warn(tfield + ": texture extension " + name + " is not supported (ignored)");
    const auto& tex = model_->textures[size_t(index)];
    if (tex.source < 0 || size_t(tex.source) >= model_->images.size())
      fail("textures[" + std::to_string(index) + "].source", "image does not exist");
    auto it = imageToTexture.find({tex.source, srgb});
    if (it == imageToTexture.end()) {
      auto bytes = imageBytes_.find(tex.source);
      const auto& img = model_->images[size_t(tex.source)];
      const std::string src = "images[" + std::to_string(tex.source) + "]" +
                              (img.uri.empty() || img.uri.rfind("data:", 0) == 0 ? "" : " '" + img.uri + "'");
      if (bytes == imageBytes_.end() || bytes->second.empty()) fail(src, "image data is missing");
      std::vector<TextureImage>& list = srgb ? textures_ : dataTextures_;
      list.push_back({bytes->second, path_ + ": " + src});  // a copy: the image may serve both
      it = imageToTexture.emplace(std::make_pair(tex.source, srgb), int(list.size()) - 1).first;
    }
    use.index = it->second;
    if (tex.sampler >= 0 && size_t(tex.sampler) < model_->samplers.size()) {
      const auto wrap = [](int w) {
        return w == 33071 ? WrapMode::ClampToEdge : w == 33648 ? WrapMode::MirroredRepeat : WrapMode::Repeat;
      };
      use.wrapS = wrap(model_->samplers[size_t(tex.sampler)].wrapS);
      use.wrapT = wrap(model_->samplers[size_t(tex.sampler)].wrapT);
    }
    return use;
  };
  for (size_t i = 0; i < model_->materials.size(); ++i) {
    const auto& gm = model_->materials[i];
    const std::string field = "materials[" + std::to_string(i) + "]";
    const std::string pbr = field + ".pbrMetallicRoughness";
    Material m;
    m.name = gm.name;
    const auto& f = gm.pbrMetallicRoughness.baseColorFactor;
    if (f.size() >= 3) {
      m.baseColorFactor = Vec3(float(f[0]), float(f[1]), float(f[2]));
      if (!isFinite(m.baseColorFactor) || m.baseColorFactor.x < 0 || m.baseColorFactor.y < 0 || m.baseColorFactor.z < 0)
        fail(pbr + ".baseColorFactor", "must be finite and non-negative");
    }
    // Coverage (core/scene/alpha.h): alpha = baseColorFactor[3] x the texture's alpha.
    if (gm.alphaMode == "MASK") m.alphaMode = AlphaMode::Mask;
    else if (gm.alphaMode == "BLEND") m.alphaMode = AlphaMode::Blend;
    else if (!gm.alphaMode.empty() && gm.alphaMode != "OPAQUE")
      fail(field + ".alphaMode", "expected OPAQUE, MASK or BLEND, got '" + gm.alphaMode + "'");
    if (f.size() >= 4) {
      m.alpha = float(f[3]);
      if (!(m.alpha >= 0.0f && m.alpha <= 1.0f))
        fail(pbr + ".baseColorFactor", "alpha (the 4th component) must be in [0, 1]");
    }
    m.alphaCutoff = float(gm.alphaCutoff);
    if (!(m.alphaCutoff >= 0.0f) || !std::isfinite(m.alphaCutoff)) fail(field + ".alphaCutoff", "must be a finite number >= 0");
    // glTF 2.0 bounds roughnessFactor to [0, 1] (the reflection lobe of
    // `reflocc` is defined there; NaN fails the test too).
    const double roughness = gm.pbrMetallicRoughness.roughnessFactor;
    if (!(roughness >= 0.0 && roughness <= 1.0))
      fail(pbr + ".roughnessFactor", "must be in [0, 1], got " + number(roughness));
    m.roughnessFactor = float(roughness);
    if (gm.emissiveFactor.size() >= 3 && (gm.emissiveFactor[0] > 0 || gm.emissiveFactor[1] > 0 || gm.emissiveFactor[2] > 0))
      warn("emission is ignored by ambient passes");
    const auto& bt = gm.pbrMetallicRoughness.baseColorTexture;
    const TextureUse base = textureUse(bt.index, bt.texCoord, bt.extensions, pbr + ".baseColorTexture", true);
    m.texture = base.index, m.wrapS = base.wrapS, m.wrapT = base.wrapT, m.transform = base.transform;
    const auto& rt = gm.pbrMetallicRoughness.metallicRoughnessTexture;
    const TextureUse rough = textureUse(rt.index, rt.texCoord, rt.extensions, pbr + ".metallicRoughnessTexture", false);
    m.roughnessTexture = rough.index, m.roughnessWrapS = rough.wrapS, m.roughnessWrapT = rough.wrapT;
    m.roughnessTransform = rough.transform;
    // normalTexture: linear data (never sRGB-decoded), decoded only when a
    // scene built with normal maps renders (Scene::decodeNormalMaps).
    const auto& nt = gm.normalTexture;
    const TextureUse normal = textureUse(nt.index, nt.texCoord, nt.extensions, field + ".normalTexture", false);
    if (normal.index >= 0) {
      if (!std::isfinite(nt.scale)) fail(field + ".normalTexture.scale", "must be finite");
      m.normalTexture = normal.index, m.normalWrapS = normal.wrapS, m.normalWrapT = normal.wrapT;
      m.normalTransform = normal.transform, m.normalScale = float(nt.scale);
    }
    materials_.push_back(std::move(m));
  }
  imageBytes_.clear();
}

Matrix4d GltfDocument::localMatrix(int index, const std::string& field) const {
  const tinygltf::Node& n = model_->nodes[size_t(index)];
  if (n.matrix.size() == 16) {
    Matrix4d m;
    for (int i = 0; i < 16; ++i) m[size_t(i)] = n.matrix[size_t(i)];
    for (double v : m)
      if (!std::isfinite(v)) fail(field + ".matrix", "not finite");
    return m;
  }
  double t[3] = {0, 0, 0}, r[4] = {0, 0, 0, 1}, s[3] = {1, 1, 1};
  if (n.translation.size() == 3) std::copy(n.translation.begin(), n.translation.end(), t);
  if (n.rotation.size() == 4) std::copy(n.rotation.begin(), n.rotation.end(), r);
  if (n.scale.size() == 3) std::copy(n.scale.begin(), n.scale.end(), s);
  return trsMatrix(t, r, s, field);
}

// T x R x S, glTF's order. The defaults (no translation, the identity
// quaternion, unit scale) give the identity factors exactly, so a node
// without a field and a node with its default value agree bit for bit.
Matrix4d GltfDocument::trsMatrix(const double tr[3], const double rot[4], const double sc[3], const std::string& field) const {
  Matrix4d t = identity4(), r = identity4(), s = identity4();
  t[12] = tr[0], t[13] = tr[1], t[14] = tr[2];
  double x = rot[0], y = rot[1], z = rot[2], w = rot[3];
  const double len = std::sqrt(x * x + y * y + z * z + w * w);
  if (!(len > 0) || !std::isfinite(len)) fail(field + ".rotation", "not a valid quaternion");
  x /= len, y /= len, z /= len, w /= len;
  r = {1 - 2 * (y * y + z * z), 2 * (x * y + z * w),     2 * (x * z - y * w),     0,
       2 * (x * y - z * w),     1 - 2 * (x * x + z * z), 2 * (y * z + x * w),     0,
       2 * (x * z + y * w),     2 * (y * z - x * w),     1 - 2 * (x * x + y * y), 0,
       0, 0, 0, 1};
  s[0] = sc[0], s[5] = sc[1], s[10] = sc[2];
  const Matrix4d m = mul(t, mul(r, s));
  for (double v : m)
    if (!std::isfinite(v)) fail(field, "transform is not finite");
  return m;
}

// Whether a node's local transform hides its subtree (true: a zero scale on
// all three axes, the upper 3 x 3 all zero), refusing a singular one that
// does not: a zero on one or two axes, or axes that are coplanar, flatten the
// meshes below into a plane or a line whose normals are meaningless - a pass
// that looks plausible and is wrong. glTF 2.0 §3.5.3 requires transforms
// that decompose into translation, rotation and scale, and its
// implementation note on animation lets a zero scale on all axes hide a node
// and its children (docs/scenes.md "What the loader refuses").
bool GltfDocument::checkLinear(const Matrix4d& m, const std::string& field) const {
  double len[3];
  for (int c = 0; c < 3; ++c) len[c] = std::sqrt(m[4 * c] * m[4 * c] + m[4 * c + 1] * m[4 * c + 1] + m[4 * c + 2] * m[4 * c + 2]);
  if (len[0] == 0 && len[1] == 0 && len[2] == 0) return true;
  const double det = m[0] * (m[5] * m[10] - m[9] * m[6]) - m[4] * (m[1] * m[10] - m[9] * m[2]) + m[8] * (m[1] * m[6] - m[5] * m[2]);
  // |det| relative to the product of the axes' lengths: the sine-like volume
  // of the unit axes, 1 for any rotation and scale, 0 when they collapse.
  // 1e-6 leaves room for a matrix written with float's 7 digits.
  if (!(std::abs(det) > 1e-6 * len[0] * len[1] * len[2]))
    fail(field, "the transform is singular (axis lengths " + number(len[0]) + ", " + number(len[1]) + ", " + number(len[2]) +
                    ", determinant " + number(det) + "): it flattens the meshes below it; a zero scale is allowed on all three "
                    "axes only (it hides the node)");
  return false;
}

// Checks the hierarchy below `index` and records it in traversal order:
// nodes, their static transforms, the mesh uses and the cameras. Poses
// (pose()) walk the record.
void GltfDocument::visit(int index, int parent, std::vector<int>& stack, std::vector<char>& visited) {
  const std::string field = "nodes[" + std::to_string(index) + "]";
  if (index < 0 || size_t(index) >= model_->nodes.size()) fail(field, "node does not exist");
  for (int s : stack)
    if (s == index) fail(field, "cycle in the node hierarchy");
  // glTF requires a tree: a node reached twice has two parents (and a file
  // that lists nodes twice per level would otherwise explode as 2^depth).
  if (visited[size_t(index)]) fail(field, "node has more than one parent (the hierarchy must be a tree)");
  visited[size_t(index)] = 1;
  if (stack.size() > 1000) fail(field, "node hierarchy deeper than 1000");
  const tinygltf::Node& n = model_->nodes[size_t(index)];
  staticLocal_[size_t(index)] = localMatrix(index, field);
  const size_t slot = visits_.size();
  visits_.push_back({index, parent});
  if (n.skin >= 0) warn("skinned meshes render in their bind pose");
  if (n.mesh >= 0) {
    if (size_t(n.mesh) >= model_->meshes.size()) fail(field + ".mesh", "mesh " + std::to_string(n.mesh) + " does not exist");
    // Named by the node, else by its mesh (what exporters name), else by its place.
    const std::string& meshName = model_->meshes[size_t(n.mesh)].name;
    uses_.push_back({n.mesh, {}, !n.name.empty() ? n.name : !meshName.empty() ? meshName : field, index});
    useVisits_.push_back(slot);
  }
  if (n.camera >= 0) {
    if (size_t(n.camera) >= model_->cameras.size())
      fail(field + ".camera", "camera " + std::to_string(n.camera) + " does not exist");
    cameraVisits_.push_back({slot, n.camera});
  }
  stack.push_back(index);
  for (int c : n.children) {
    if (c >= 0 && size_t(c) < parents_.size() && !visited[size_t(c)]) parents_[size_t(c)] = index;
    visit(c, int(slot), stack, visited);
  }
  stack.pop_back();
}

void GltfDocument::decodeNodes() {
  std::vector<char> visited(model_->nodes.size(), 0);
  staticLocal_.assign(model_->nodes.size(), identity4());
  parents_.assign(model_->nodes.size(), -1);
  std::vector<int> roots;
  if (!model_->scenes.empty()) {
    int s = model_->defaultScene >= 0 ? model_->defaultScene : 0;
    if (size_t(s) >= model_->scenes.size()) fail("scene", "scene " + std::to_string(s) + " does not exist");
    if (model_->scenes.size() > 1)
      warn("file has " + std::to_string(model_->scenes.size()) + " scenes; rendering scene " + std::to_string(s));
    roots = model_->scenes[size_t(s)].nodes;
  } else {
    std::vector<bool> isChild(model_->nodes.size(), false);
    for (const auto& n : model_->nodes)
      for (int c : n.children)
        if (c >= 0 && size_t(c) < isChild.size()) isChild[size_t(c)] = true;
    for (size_t i = 0; i < model_->nodes.size(); ++i)
      if (!isChild[i]) roots.push_back(int(i));
  }
  std::vector<int> stack;
  for (int r : roots) visit(r, -1, stack, visited);
  if (model_->scenes.empty())  // every node is reachable from a root unless it sits on a cycle
    for (size_t i = 0; i < model_->nodes.size(); ++i)
      if (!visited[i]) fail("nodes[" + std::to_string(i) + "]", "cycle in the node hierarchy");
  animations_ = readAnimations(*this);
  for (const Animation& a : animations_) animationInfo_.push_back({a.name, a.start, a.end, a.fileChannels, a.nodes});
  Pose p = pose(std::nullopt, {});
  uses_ = std::move(p.uses);
  cameras_ = std::move(p.cameras);
}

std::string GltfDocument::nodeLabel(int node) const {
  const std::string& name = model_->nodes.at(size_t(node)).name;
  return name.empty() ? "nodes[" + std::to_string(node) + "]" : name;
}

std::vector<size_t> GltfDocument::selectAnimations(const std::vector<std::string>& selection) const {
  return obscura::selectAnimations(*this, animations_, selection);
}

GltfDocument::Pose GltfDocument::pose(std::optional<double> seconds, const std::vector<std::string>& selection) const {
  const std::vector<size_t> played = selectAnimations(selection);
  // The played channels' values, by node: translation, rotation, scale,
  // starting from the node's own (a channel replaces one of the three).
  struct Trs {
    double t[3] = {0, 0, 0}, r[4] = {0, 0, 0, 1}, s[3] = {1, 1, 1};
  };
  std::map<int, Trs> animated;
  if (seconds) {
    if (!std::isfinite(*seconds)) throw Error(path_ + ": " + settingName(Setting::Time) + ": the time is not finite");
    for (size_t a : played)
      for (const AnimationChannel& ch : animations_[a].channels) {
        auto [it, fresh] = animated.try_emplace(ch.node);
        Trs& x = it->second;
        if (fresh) {
          const tinygltf::Node& n = model_->nodes[size_t(ch.node)];
          if (n.translation.size() == 3) std::copy(n.translation.begin(), n.translation.end(), x.t);
          if (n.rotation.size() == 4) std::copy(n.rotation.begin(), n.rotation.end(), x.r);
          if (n.scale.size() == 3) std::copy(n.scale.begin(), n.scale.end(), x.s);
        }
        ch.sampler.evaluate(*seconds, ch.path == AnimationPath::Translation ? x.t : ch.path == AnimationPath::Rotation ? x.r : x.s);
      }
  }
  std::vector<Matrix4d> world(visits_.size());
  std::vector<char> moved(visits_.size(), 0);
  std::vector<int> hiddenBy(visits_.size(), -1);  // the node whose zero scale hides the visit, -1: none
  for (size_t i = 0; i < visits_.size(); ++i) {
    const Visit& v = visits_[i];
    auto it = animated.find(v.node);
    const std::string field = it == animated.end() ? "nodes[" + std::to_string(v.node) + "]"
                                                   : "nodes[" + std::to_string(v.node) + "] (animated, at " + formatFloat(*seconds) + " s)";
    const Matrix4d local = it == animated.end() ? staticLocal_[size_t(v.node)] : trsMatrix(it->second.t, it->second.r, it->second.s, field);
    world[i] = mul(v.parent < 0 ? identity4() : world[size_t(v.parent)], local);
    moved[i] = it != animated.end() || (v.parent >= 0 && moved[size_t(v.parent)]);
    hiddenBy[i] = v.parent >= 0 ? hiddenBy[size_t(v.parent)] : -1;
    if (hiddenBy[i] < 0 && checkLinear(local, field)) hiddenBy[i] = v.node;
  }
  Pose p;
  p.uses = uses_;  // the static pose's (or, while decoding, the uses without transforms)
  for (size_t i = 0; i < p.uses.size(); ++i) {
    p.uses[i].world = world[useVisits_[i]];
    p.uses[i].animated = moved[useVisits_[i]] != 0;
    const int by = hiddenBy[useVisits_[i]];
    p.uses[i].hidden = by >= 0;
    p.uses[i].hiddenBy = by >= 0 ? "nodes[" + std::to_string(by) + "]" : "";
  }
  for (const CameraVisit& c : cameraVisits_) {
    const int node = visits_[c.visit].node;
    std::optional<Camera> cam = makeCamera(node, c.camera, world[c.visit], "nodes[" + std::to_string(node) + "]");
    if (!cam) continue;
    cam->animated = moved[c.visit] != 0;
    p.cameras.push_back(std::move(*cam));
  }
  // `--camera INDEX` means the index in the file's cameras[], whatever the
  // order nodes were visited in.
  std::stable_sort(p.cameras.begin(), p.cameras.end(), [](const Camera& a, const Camera& b) { return a.fileIndex < b.fileIndex; });
  return p;
}

std::optional<Camera> GltfDocument::makeCamera(int nodeIndex, int index, const Matrix4d& world, const std::string& field) const {
  const tinygltf::Node& node = model_->nodes[size_t(nodeIndex)];
  const std::string cfield = "cameras[" + std::to_string(index) + "]";
  const auto& gc = model_->cameras[size_t(index)];
  if (gc.type != "perspective") {
    warn(cfield + ": " + gc.type + " cameras are not supported (skipped)");
    return std::nullopt;
  }
  Camera c;
  c.fileIndex = index;
  c.name = !gc.name.empty() ? gc.name : !node.name.empty() ? node.name : cfield;
  c.yfov = float(gc.perspective.yfov);
  if (!(c.yfov > 0.0f && c.yfov < kPi)) fail(cfield + ".perspective.yfov", "must be in (0, pi)");
  c.znear = float(gc.perspective.znear);
  if (!(c.znear >= 0.0f) || !std::isfinite(c.znear)) fail(cfield + ".perspective.znear", "must be >= 0");
  if (!inTraceableRange(c.znear))
    fail(cfield + ".perspective.znear", number(gc.perspective.znear) + " is outside the range Embree traces (<= 1e+16)");
  // A zfar beyond any coordinate the scene may have is as good as none.
  // glTF 2.0: zfar, when given, is > 0 and > znear (tinygltf's 0 stands for
  // an absent zfar, an infinite projection). One at or before znear clipped
  // every ray: an empty pass with exit status 0.
  if (gc.perspective.zfar < 0 || (gc.perspective.zfar > 0 && !(gc.perspective.zfar > gc.perspective.znear)))
    fail(cfield + ".perspective.zfar", "must be greater than znear (" + number(gc.perspective.znear) + "), got " +
                                           number(gc.perspective.zfar));
  c.zfar = gc.perspective.zfar > 0 && gc.perspective.zfar <= double(kMaxCoordinate) ? float(gc.perspective.zfar) : kInfinity;
  // Rigid part of the node transform: orthonormalized axes, so a scaled
  // camera node (legal in files, meaningless for a pinhole) still works.
  Affine a = Affine::fromColumnMajor4x4(world.data());
  Vec3 x(a.m[0][0], a.m[1][0], a.m[2][0]), y(a.m[0][1], a.m[1][1], a.m[2][1]);
  if (!(length(x) > 0) || !(length(y) > 0)) fail(field, "camera transform is degenerate");
  x = normalize(x);
  y = normalize(y - x * dot(x, y));
  const Vec3 z = cross(x, y);
  if (!isFinite(z)) fail(field, "camera transform is degenerate");
  for (int r = 0; r < 3; ++r) a.m[r][0] = x[r], a.m[r][1] = y[r], a.m[r][2] = z[r];
  c.toWorld = a;
  checkCameraRange(c, path_ + ": " + field + " (" + cfield + ")");
  return c;
}

// --- accessors ---------------------------------------------------------------

GltfDocument::View GltfDocument::view(int accessor, const std::string& field) const {
  const std::string f = field + " (accessors[" + std::to_string(accessor) + "])";
  if (accessor < 0 || size_t(accessor) >= model_->accessors.size())
    fail(field, "accessor " + std::to_string(accessor) + " does not exist");
  const auto& a = model_->accessors[size_t(accessor)];
  if (a.sparse.isSparse) fail(f, "sparse accessors are not supported");
  View v;
  v.count = a.count;
  v.componentType = a.componentType;
  v.normalized = a.normalized;
  v.components = tinygltf::GetNumComponentsInType(uint32_t(a.type));
  const int csize = tinygltf::GetComponentSizeInBytes(uint32_t(a.componentType));
  if (v.components <= 0 || csize <= 0) fail(f, "invalid type or componentType");
  if (a.bufferView < 0 || size_t(a.bufferView) >= model_->bufferViews.size()) fail(f, "bufferView missing or out of range");
  const std::string bvField = "bufferViews[" + std::to_string(a.bufferView) + "]";
  const auto& bv = model_->bufferViews[size_t(a.bufferView)];
  if (bv.buffer < 0 || size_t(bv.buffer) >= model_->buffers.size()) fail(f, "buffer out of range");
  const auto& buf = model_->buffers[size_t(bv.buffer)];
  const size_t elem = size_t(csize) * size_t(v.components);
  v.stride = bv.byteStride ? bv.byteStride : elem;
  if (v.stride < elem) fail(f, "byteStride smaller than the element");
  if (bv.byteOffset > buf.data.size() || bv.byteLength > buf.data.size() - bv.byteOffset)
    fail(bvField, "extends past the end of its buffer");
  if (v.count > 0) {
    // byteOffset + (count - 1) * stride + elem <= byteLength, without
    // overflow: a count near SIZE_MAX / stride must not wrap around.
    const size_t room = bv.byteLength;
    if (a.byteOffset > room || elem > room - a.byteOffset || (v.count - 1) > (room - a.byteOffset - elem) / v.stride)
      fail(f, "count " + std::to_string(v.count) + " x stride " + std::to_string(v.stride) + " from byteOffset " +
                  std::to_string(a.byteOffset) + " extends past the end of its bufferView (" + bvField + ", byteLength " +
                  std::to_string(bv.byteLength) + ")");
  }
  v.data = buf.data.data() + bv.byteOffset + a.byteOffset;
  return v;
}

namespace {
float component(const unsigned char* p, int componentType, bool normalized, int c) {
  switch (componentType) {
    case TINYGLTF_COMPONENT_TYPE_FLOAT: {
      float f;
      std::memcpy(&f, p + 4 * c, 4);
      return f;
    }
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE: return normalized ? p[c] / 255.0f : p[c];
    case TINYGLTF_COMPONENT_TYPE_BYTE: {
      const float x = float(int8_t(p[c]));
      return normalized ? std::max(x / 127.0f, -1.0f) : x;
    }
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT: {
      uint16_t x;
      std::memcpy(&x, p + 2 * c, 2);
      return normalized ? x / 65535.0f : float(x);
    }
    case TINYGLTF_COMPONENT_TYPE_SHORT: {
      int16_t x;
      std::memcpy(&x, p + 2 * c, 2);
      return normalized ? std::max(x / 32767.0f, -1.0f) : float(x);
    }
    default: return 0.0f;
  }
}
}  // namespace

std::vector<float> GltfDocument::readFloats(int accessor, const std::string& field, int n) const {
  const View v = view(accessor, field);
  if (v.components != n) fail(field, "must be VEC" + std::to_string(n));
  std::vector<float> out(v.count * size_t(n));
  for (size_t i = 0; i < v.count; ++i)
    for (int c = 0; c < n; ++c) {
      const float x = component(v.data + i * v.stride, v.componentType, v.normalized, c);
      if (!std::isfinite(x)) fail(field, "element " + std::to_string(i) + " is NaN or infinite");
      out[i * size_t(n) + size_t(c)] = x;
    }
  return out;
}

std::vector<Vec3> GltfDocument::readVec3(int accessor, const std::string& field, bool positions) const {
  const std::vector<float> f = readFloats(accessor, field, 3);
  std::vector<Vec3> out(f.size() / 3);
  for (size_t i = 0; i < out.size(); ++i) {
    out[i] = Vec3(f[3 * i], f[3 * i + 1], f[3 * i + 2]);
    if (positions)
      for (int c = 0; c < 3; ++c)
        if (!inTraceableRange(out[i][c]))
          fail(field + " (accessors[" + std::to_string(accessor) + "])",
               "vertex " + std::to_string(i) + " coordinate " + number(out[i][c]) +
                   " is outside the range Embree traces (|x| <= 1e+16)");
  }
  return out;
}

std::vector<uint32_t> GltfDocument::readIndices(int accessor, const std::string& field, size_t vertexCount) const {
  const View v = view(accessor, field);
  if (v.components != 1) fail(field, "must be SCALAR");
  std::vector<uint32_t> out(v.count);
  for (size_t i = 0; i < v.count; ++i) {
    const unsigned char* p = v.data + i * v.stride;
    uint32_t x;
    switch (v.componentType) {
      case TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE: x = p[0]; break;
      case TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT: { uint16_t s; std::memcpy(&s, p, 2); x = s; break; }
      case TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT: std::memcpy(&x, p, 4); break;
      default: fail(field, "index componentType must be an unsigned integer type");
    }
    if (x >= vertexCount)
      fail(field, "index " + std::to_string(x) + " at element " + std::to_string(i) + " is out of range (" +
                      std::to_string(vertexCount) + " vertices)");
    out[i] = x;
  }
  return out;
}

const std::vector<GltfDocument::Primitive>& GltfDocument::mesh(int index) const {
  auto it = meshes_.find(index);
  if (it == meshes_.end()) it = meshes_.emplace(index, decodeMesh(index)).first;
  return it->second;
}

std::vector<GltfDocument::Primitive> GltfDocument::decodeMesh(int meshIndex) const {
  const auto& mesh = model_->meshes[size_t(meshIndex)];
  std::vector<Primitive> out;
  for (size_t pi = 0; pi < mesh.primitives.size(); ++pi) {
    const auto& gp = mesh.primitives[pi];
    const std::string field = "meshes[" + std::to_string(meshIndex) + "].primitives[" + std::to_string(pi) + "]";
    if (gp.mode != TINYGLTF_MODE_TRIANGLES && gp.mode != TINYGLTF_MODE_TRIANGLE_STRIP && gp.mode != TINYGLTF_MODE_TRIANGLE_FAN &&
        gp.mode != -1) {
      warn("point and line primitives are not supported (skipped)");
      continue;
    }
    if (!gp.targets.empty()) warn("morph targets are not supported (base shape rendered)");
    auto pos = gp.attributes.find("POSITION");
    if (pos == gp.attributes.end()) fail(field + ".attributes", "POSITION is missing");
    Primitive d;
    d.field = field;
    d.positions = readVec3(pos->second, field + ".attributes.POSITION", true);
    if (auto n = gp.attributes.find("NORMAL"); n != gp.attributes.end()) {
      d.normals = readVec3(n->second, field + ".attributes.NORMAL", false);
      if (d.normals.size() != d.positions.size()) fail(field + ".attributes.NORMAL", "count differs from POSITION");
    }
    if (gp.attributes.count("COLOR_0")) warn("vertex colors (COLOR_0) are not supported (ignored)");
    if (gp.material >= 0) {
      if (size_t(gp.material) >= materials_.size())
        fail(field + ".material", "material " + std::to_string(gp.material) + " does not exist");
      d.material = gp.material;
      if (materials_[size_t(gp.material)].texture >= 0 && !gp.attributes.count("TEXCOORD_0"))
        warn(field + ": textured material without TEXCOORD_0 (texture ignored)");
    }
    // Texture coordinates serve a texture, the displacement of a subdivided
    // mesh and integrators that work in texture space (containment), so
    // they are kept whenever the file has them (8 bytes a vertex).
    if (auto t = gp.attributes.find("TEXCOORD_0"); t != gp.attributes.end()) {
      d.uvs = readFloats(t->second, field + ".attributes.TEXCOORD_0", 2);
      if (d.uvs.size() != 2 * d.positions.size()) fail(field + ".attributes.TEXCOORD_0", "count differs from POSITION");
    }
    // Tangents serve a normal map only (16 bytes a vertex): read for those.
    if (auto t = gp.attributes.find("TANGENT");
        t != gp.attributes.end() && d.material >= 0 && materials_[size_t(d.material)].normalTexture >= 0) {
      d.tangents = readFloats(t->second, field + ".attributes.TANGENT", 4);
      if (d.tangents.size() != 4 * d.positions.size()) fail(field + ".attributes.TANGENT", "count differs from POSITION");
    }
    std::vector<uint32_t> idx;
    if (gp.indices >= 0) {
      idx = readIndices(gp.indices, field + ".indices", d.positions.size());
    } else {
      idx.resize(d.positions.size());
      for (size_t i = 0; i < idx.size(); ++i) idx[i] = uint32_t(i);
    }
    // Triangle lists from every triangle mode.
    if (gp.mode == TINYGLTF_MODE_TRIANGLE_STRIP) {
      for (size_t i = 2; i < idx.size(); ++i) {
        const bool odd = i % 2 == 1;
        d.indices.insert(d.indices.end(), {idx[i - 2], odd ? idx[i] : idx[i - 1], odd ? idx[i - 1] : idx[i]});
      }
    } else if (gp.mode == TINYGLTF_MODE_TRIANGLE_FAN) {
      for (size_t i = 2; i < idx.size(); ++i) d.indices.insert(d.indices.end(), {idx[0], idx[i - 1], idx[i]});
    } else {
      if (idx.size() % 3 != 0) fail(field + (gp.indices >= 0 ? ".indices" : ".attributes.POSITION"), "count is not a multiple of 3");
      d.indices = std::move(idx);
    }
    if (d.indices.empty()) continue;
    out.push_back(std::move(d));
  }
  return out;
}

std::vector<std::pair<std::string, std::string>> gltfExternalFiles(const std::string& path) {
  std::vector<std::pair<std::string, std::string>> files;
  std::ifstream in(path, std::ios::binary);
  if (!in) return files;
  // A .glb's header and JSON chunk only (its binary chunk may be large).
  std::vector<unsigned char> bytes(20);
  in.read(reinterpret_cast<char*>(bytes.data()), 20);
  bytes.resize(size_t(in.gcount()));
  if (isGlb(bytes) && bytes.size() == 20) {
    uint32_t length = 0;
    std::memcpy(&length, bytes.data() + 12, 4);
    std::error_code ec;
    const uintmax_t size = fs::file_size(path, ec);
    if (ec || uintmax_t(length) > size - 20) return files;  // a chunk past the end: the loader refuses it
    bytes.resize(20 + size_t(length));
    in.read(reinterpret_cast<char*>(bytes.data() + 20), std::streamsize(length));
    bytes.resize(20 + size_t(in.gcount()));
  } else {
    bytes.insert(bytes.end(), std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
  }
  const std::string text = jsonText(bytes);
  // Too deep for the parser: the loader refuses the file (GltfDocument::read).
  if (jsonDepth(reinterpret_cast<const unsigned char*>(text.data()), text.size()).first > kMaxJsonDepth) return files;
  const json root = json::parse(text, nullptr, /*allow_exceptions=*/false);
  if (!root.is_object()) return files;
  const fs::path base = fs::path(path).parent_path();
  const auto place = [&](const std::string& name) { return fs::path(name).is_absolute() || base.empty() ? name : (base / name).string(); };
  for (const char* array : {"buffers", "images"}) {
    auto it = root.find(array);
    if (it == root.end() || !it->is_array()) continue;
    for (size_t i = 0; i < it->size(); ++i) {
      if (!(*it)[i].is_object()) continue;
      auto uri = (*it)[i].find("uri");
      if (uri == (*it)[i].end() || !uri->is_string() || uri->get<std::string>().rfind("data:", 0) == 0) continue;
      files.emplace_back(std::string(array) + "[" + std::to_string(i) + "]", place(decodeUri(uri->get<std::string>())));
    }
  }
  // extras.obscura.displacement.map of nodes and meshes: a path as written,
  // relative to the file (core/load/gltf_loader.cpp parseDisplacement).
  for (const char* array : {"nodes", "meshes"}) {
    auto it = root.find(array);
    if (it == root.end() || !it->is_array()) continue;
    for (size_t i = 0; i < it->size(); ++i) {
      const json* v = &(*it)[i];
      for (const char* key : {"extras", "obscura", "displacement", "map"}) {
        if (!v->is_object() || !v->contains(key)) {
          v = nullptr;
          break;
        }
        v = &(*v)[key];
      }
      if (v && v->is_string() && !v->get<std::string>().empty())
        files.emplace_back(std::string(array) + "[" + std::to_string(i) + "].extras.obscura.displacement.map",
                           place(v->get<std::string>()));
    }
  }
  return files;
}

}  // namespace obscura
