// How a scene file is turned into a Scene: the options every loader takes.
#pragma once

#include <cstddef>
#include <array>
#include <optional>
#include <string>
#include <vector>

#include "core/scene/camera.h"
#include "core/scene/objects.h"
#include "core/subd/subdivision.h"

namespace obscura {

struct LoadOptions {
  bool robust = false;  // Scene::setRobust
  // glTF normalTexture bends the shading normal (docs/scenes.md "Normal
  // maps"); false: every normal map is ignored, as if the file had none.
  bool normalMaps = true;
  // Subdivision of polygon cages (OBJ): off by default; the scheme and the
  // uniform level when on, and the memory a refinement may take.
  bool subdivision = false;
  SubdivisionScheme scheme = SubdivisionScheme::CatmullClark;
  SubdivisionBackend backend = SubdivisionBackend::OpenSubdiv;
  int subdivisionLevel = 2;
  size_t maxMemoryBytes = size_t(8) << 30;
  // Adaptive refinement instead of the uniform level, when > 0: no edge of
  // the refined surface longer than this many pixels seen from `camera` at
  // imageWidth x imageHeight (the cage's edges are measured; OpenSubdiv
  // refines uniformly to the level the longest one needs, Embree
  // tessellates each edge to its own rate).
  double maxEdgePixels = 0;
  // Load cages unrefined and undisplaced whatever the file or the options
  // say (the cheap first read that finds the camera for maxEdgePixels).
  bool unrefined = false;
  std::optional<Camera> camera;
  int imageWidth = 0, imageHeight = 0;
  // Displacement of subdivided OBJ cages, and of subdivided glTF meshes
  // without a displacement in their extras: a height map, moved along the
  // limit normal by scale * (h - midlevel) (scene units). Also the defaults
  // of a glTF displacement's scale and midlevel.
  std::string displacementMap;
  double displacementScale = 0.1;
  double displacementMidlevel = 0.5;
  // Roles set on objects by name (--object), applied in order after the
  // file's own (core/scene/objects.h).
  std::vector<ObjectOverride> objectOverrides;
  // Animation (glTF): the time in seconds at which the file's animations
  // are applied to its nodes (GltfDocument::pose); nullopt = the static
  // pose, no animation applied. An OBJ has no animation: a time is refused.
  std::optional<double> time;
  // The animations played at `time`: names or indices; empty = all of them.
  std::vector<std::string> animations;
  // Motion blur: the shutter, [open, close] in seconds (absolute times of
  // the animation), or none. Animated nodes that move within it become
  // moving instances, an animated camera a moving camera (core/scene/motion.h);
  // the rest is placed at `time` as without a shutter.
  std::optional<std::array<double, 2>> shutter;
};

}  // namespace obscura
