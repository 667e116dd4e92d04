// The EXR header of a pass, in one place: every attribute a pass records
// (docs/exr.md "The EXR pass"), the camera in OpenEXR's standard attributes,
// and which attributes describe one run of a render rather than its image -
// the one list that `obscura merge` lets differ between region tiles and that
// a checkpoint's fingerprint leaves out.
#pragma once

#include <string>
#include <vector>

#include "app/options.h"
#include "core/image/image_io.h"
#include "core/render/render.h"
#include "core/scene/camera.h"
#include "core/scene/scene.h"
#include <obscura/integrator.h>

namespace obscura {

// A pass of a multi-pass render as the header records it.
struct LayerInfo {
  std::string layer;
  const IntegratorDescriptor* integrator = nullptr;
  const ParamSet* params = nullptr;
};

// Everything the header of a pass records (docs/exr.md "The EXR pass").
struct PassInfo {
  std::string scenePath;
  const Camera& camera;
  const IntegratorDescriptor& integrator;
  const ParamSet& params;
  const RenderSettings& settings;
  const RenderStats& stats;
  std::string filterName;
  bool robust = false;
  const SceneArgs* sceneArgs = nullptr;  // subdivision and displacement options, when given
  const Scene* scene = nullptr;          // its objects' roles, when given
  double bvhSeconds = 0;
  // A multi-pass render's passes, the primary first (integrator and params
  // above are the primary's); empty for a single pass.
  std::vector<LayerInfo> layers;
};
ExrOptions passHeader(const PassInfo& info);


// Attributes that describe one run of a render, not the image: its timings,
// ray counts, thread count and resumes. A resumed or split render has other
// values in them and the same image, so a checkpoint's fingerprint leaves
// them out and `obscura merge` sums or drops them.
inline bool isRunAttribute(const std::string& name) {
  return name == "obscura:renderTime" || name == "obscura:bvhBuildTime" || name == "obscura:denoiseTime" ||
         name == "obscura:threads" || name == "obscura:checkpointRuns" || name.rfind("obscura:rays:", 0) == 0;
}

// Attributes a region tile of a render may carry with its own value: the
// run attributes, its region, and the time the file was written (DateTime,
// which OpenImageIO stamps on each file). Every other attribute must be the
// same in every tile (app/merge.h).
inline bool isPerTileAttribute(const std::string& name) {
  return isRunAttribute(name) || name == "obscura:region" || name == "DateTime";
}

}  // namespace obscura
