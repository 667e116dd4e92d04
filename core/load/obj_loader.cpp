#include "core/load/obj_loader.h"
#include "core/util/input_file.h"

#include <tiny_obj_loader.h>

#include <charconv>
#include <climits>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <map>
#include <string_view>
#include <vector>

#include "core/load/cage.h"
#include <obscura/error.h>
#include "core/util/option_names.h"
#include "core/subd/subdivision.h"

namespace obscura {
namespace {

// tinyobjloader keeps a face's vertex count in one byte (a 259-gon becomes a
// triangle and the next face reads the wrong indices; a 256-gon has "0"
// vertices) and reads "nan" or a malformed number as 0. Neither is visible
// after parsing, so the text is checked first: every f line has at most 255
// vertex references, every v and vt line only finite numbers (v: at least 3).
void prescanObj(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw Error(path + ": cannot open");
  std::string line;
  size_t lineNo = 0;
  const auto fail = [&](const std::string& why) { throw Error(path + ": line " + std::to_string(lineNo) + ": " + why); };
  std::vector<std::string_view> tok;  // reused: one allocation for the file
  while (std::getline(in, line)) {
    ++lineNo;
    std::string_view s(line);
    if (const size_t hash = s.find('#'); hash != std::string_view::npos) s = s.substr(0, hash);
    tok.clear();
    for (size_t i = 0; i < s.size();) {
      while (i < s.size() && (s[i] == ' ' || s[i] == '\t' || s[i] == '\r')) ++i;
      const size_t b = i;
      while (i < s.size() && s[i] != ' ' && s[i] != '\t' && s[i] != '\r') ++i;
      if (i > b) tok.push_back(s.substr(b, i - b));
    }
    if (tok.empty()) continue;
    // tinyobjloader reads a material library to its end: a FIFO or a
    // device named here would block it or take all memory.
    if (tok[0] == "mtllib")
      for (size_t k = 1; k < tok.size(); ++k) {
        const std::filesystem::path lib = std::filesystem::path(path).parent_path() / std::string(tok[k]);
        const std::string kind = nonRegularKind(lib.string());
        if (!kind.empty()) fail("mtllib " + lib.string() + ": is " + kind + ", not a regular file");
      }
    if (tok[0] == "f" && tok.size() - 1 > 255)
      fail("face has " + std::to_string(tok.size() - 1) + " vertices (at most 255)");
    // tinyobjloader reads an index into an int without a range check: 2147483648
    // wrapped to a negative index (reported as -2147483644) and
    // 99999999999999999999 to one that happened to be valid (it rendered).
    if (tok[0] == "f" || tok[0] == "l" || tok[0] == "p") {
      for (size_t k = 1; k < tok.size(); ++k) {
        std::string_view ref = tok[k];
        for (size_t part = 0; !ref.empty() || part == 0; ++part) {
          const size_t slash = ref.find('/');
          std::string_view t = ref.substr(0, slash);
          ref = slash == std::string_view::npos ? std::string_view() : ref.substr(slash + 1);
          if (t.empty() && part > 0) continue;  // "1//3": no texture coordinate
          if (t.size() > 1 && t[0] == '+') t.remove_prefix(1);
          long long x = 0;
          const auto [end, ec] = std::from_chars(t.data(), t.data() + t.size(), x);
          if (ec == std::errc::result_out_of_range || (ec == std::errc() && (x > INT_MAX || x < -INT_MAX)))
            fail("index '" + std::string(t) + "' in '" + std::string(tok[k]) + "' is outside [-" + std::to_string(INT_MAX) +
                 ", " + std::to_string(INT_MAX) + "]");
          if (ec != std::errc() || end != t.data() + t.size() || x == 0)
            fail("'" + std::string(tok[k]) + "' is not a vertex reference (v, v/vt, v//vn or v/vt/vn, each a non-zero integer)");
          if (slash == std::string_view::npos) break;
        }
      }
    }
    if (tok[0] != "v" && tok[0] != "vt") continue;
    if (tok[0] == "v" && tok.size() < 4) fail("a vertex needs 3 coordinates");
    for (size_t k = 1; k < tok.size(); ++k) {
      std::string_view t = tok[k];
      if (t.size() > 1 && t[0] == '+') t.remove_prefix(1);
      double x = 0;
      const auto [end, ec] = std::from_chars(t.data(), t.data() + t.size(), x);
      if (ec != std::errc() || end != t.data() + t.size() || !std::isfinite(x))
        fail((tok[0] == "v" ? "vertex coordinate '" : "texture coordinate '") + std::string(tok[k]) +
             "' is not a finite number");
    }
  }
}

}  // namespace

std::unique_ptr<Scene> loadObj(const std::string& path, const LoadOptions& options) {
  checkInputFile(path);
  if (!std::filesystem::is_regular_file(path)) throw Error(path + ": cannot open: no such file");
  prescanObj(path);
  tinyobj::ObjReaderConfig config;
  config.triangulate = false;  // keep quads and n-gons: they are the cage
  config.vertex_color = false;
  config.mtl_search_path = std::filesystem::path(path).parent_path().string();
  tinyobj::ObjReader reader;
  if (!reader.ParseFromFile(path, config)) {
    std::string why = reader.Error();
    while (!why.empty() && (why.back() == '\n' || why.back() == '\r')) why.pop_back();
    for (char& c : why)
      if (c == '\n') c = ';';
    throw Error(path + ": not a readable OBJ file: " + (why.empty() ? "parse error" : why));
  }
  const tinyobj::attrib_t& attrib = reader.GetAttrib();
  SubdivisionCage cage;
  for (size_t i = 0; i + 2 < attrib.vertices.size(); i += 3)
    cage.positions.emplace_back(attrib.vertices[i], attrib.vertices[i + 1], attrib.vertices[i + 2]);
  cage.uvs.assign(attrib.texcoords.begin(), attrib.texcoords.end());
  bool everyCornerHasUv = !cage.uvs.empty();
  for (const tinyobj::shape_t& shape : reader.GetShapes()) {
    size_t k = 0;
    for (const unsigned char n : shape.mesh.num_face_vertices) {
      cage.faceSizes.push_back(int(n));
      for (unsigned char j = 0; j < n; ++j) {
        cage.faceIndices.push_back(shape.mesh.indices[k + j].vertex_index);
        cage.uvIndices.push_back(shape.mesh.indices[k + j].texcoord_index);
        everyCornerHasUv = everyCornerHasUv && shape.mesh.indices[k + j].texcoord_index >= 0;
      }
      k += n;
    }
    // Crease tags ("t crease 2/1 a b sharpness").
    for (const tinyobj::tag_t& tag : shape.mesh.tags) {
      if (tag.name != "crease") continue;
      if (tag.intValues.size() < 2 || tag.floatValues.empty())
        throw Error(path + ": a crease tag needs two vertex indices and a sharpness");
      cage.creaseEdges.insert(cage.creaseEdges.end(), {tag.intValues[0], tag.intValues[1]});
      cage.creaseWeights.push_back(tag.floatValues[0]);
    }
  }
  if (cage.faceSizes.empty()) throw Error(path + ": no polygon faces");
  if (!everyCornerHasUv) cage.uvs.clear(), cage.uvIndices.clear();
  if (!options.displacementMap.empty()) {
    if (!options.subdivision) throw Error(path + ": displacement (" + settingName(Setting::Displacement) + ") needs " + settingName(Setting::Subdivision));
    if (!everyCornerHasUv) throw Error(path + ": displacement needs texture coordinates (vt) on every face corner");
  }

  auto scene = std::make_unique<Scene>();
  scene->sourcePath = path;
  scene->setRobust(options.robust);
  scene->sourceMeshes = 1;
  scene->flattenedMeshes = 1;
  // The cage is one object, named by its file (docs/production.md "Objects and roles").
  scene->objects.push_back({std::filesystem::path(path).filename().string(), {}});
  scene->setCurrentObject(0);
  applyObjectOverrides(scene->objects, options.objectOverrides);
  if (options.subdivision) {
    CageDisplacement disp;
    if (!options.displacementMap.empty()) {  // loaded only when used
      disp.map = std::make_shared<HeightMap>(options.displacementMap);
      disp.scale = options.displacementScale, disp.midlevel = options.displacementMidlevel;
    }
    addCage(*scene, cage, options, disp, -1, path);
  } else {
    // The cage as it is, after the same validation subdivision applies.
    validateCage(cage, SubdivisionScheme::CatmullClark, path);
    // With vt on every corner the uvs are kept (texture-space integrators
    // read them): one vertex per (position, uv) pair, so a uv seam splits
    // a vertex into copies at the same position.
    std::vector<Vec3> positions;
    std::vector<float> uvs;
    std::vector<uint32_t> corner(cage.faceIndices.size());
    if (everyCornerHasUv) {
      std::map<std::pair<int, int>, uint32_t> vertexOf;
      for (size_t c = 0; c < corner.size(); ++c) {
        const auto [it, fresh] = vertexOf.emplace(std::pair{cage.faceIndices[c], cage.uvIndices[c]}, uint32_t(positions.size()));
        if (fresh) {
          positions.push_back(cage.positions[size_t(cage.faceIndices[c])]);
          uvs.insert(uvs.end(), {cage.uvs[2 * size_t(cage.uvIndices[c])], cage.uvs[2 * size_t(cage.uvIndices[c]) + 1]});
        }
        corner[c] = it->second;
      }
    } else {
      positions = cage.positions;
      for (size_t c = 0; c < corner.size(); ++c) corner[c] = uint32_t(cage.faceIndices[c]);
    }
    std::vector<uint32_t> tris;
    size_t k = 0;
    for (const int n : cage.faceSizes) {
      for (int j = 1; j + 1 < n; ++j) tris.insert(tris.end(), {corner[k], corner[k + size_t(j)], corner[k + size_t(j) + 1]});
      k += size_t(n);
    }
    scene->setPrimitiveName(scene->addWorldPrimitive(positions, tris, {}, std::move(uvs), -1), path);
  }
  scene->commit();
  return scene;
}

}  // namespace obscura
