#include "core/obj_loader.h"

#include <tiny_obj_loader.h>

#include <filesystem>

#include "core/cage.h"
#include "core/error.h"
#include "core/settings.h"
#include "core/subdivision.h"

namespace obscura {

std::unique_ptr<Scene> loadObj(const std::string& path, const LoadOptions& options) {
  if (!std::filesystem::is_regular_file(path)) throw Error(path + ": cannot open: no such file");
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
    std::vector<uint32_t> tris;
    size_t k = 0;
    for (const int n : cage.faceSizes) {
      for (int j = 1; j + 1 < n; ++j)
        tris.insert(tris.end(), {uint32_t(cage.faceIndices[k]), uint32_t(cage.faceIndices[k + size_t(j)]),
                                 uint32_t(cage.faceIndices[k + size_t(j) + 1])});
      k += size_t(n);
    }
    scene->addWorldPrimitive(cage.positions, tris, {}, {}, -1);
  }
  scene->commit();
  return scene;
}

}  // namespace obscura
