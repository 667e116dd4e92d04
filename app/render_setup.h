// What a render is made of, from the options as typed: the settings, the
// passes and the EXR header. The command line (app/main.cpp) and the Python
// module (python/module.cpp) both build their renders here, so the same
// options give the same settings, the same messages and the same file.
#pragma once

#include "core/util/memory_budget.h"

#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "app/options.h"
#include "core/render/checkpoint.h"
#include <obscura/params.h>

namespace obscura {

struct RenderArgs : SceneArgs {
  std::string scene;  // the CLI defaults it to the bundled scene
  std::string output;
  std::string integrator = "ao";
  std::vector<std::string> params;
  bool integratorGiven = false;      // -i or -p on the command line
  std::vector<std::string> passes;   // --pass LAYER=integrator[:key=value,...]
  std::string primary;               // --primary LAYER
  int spp = 16;
  double targetError = 0;  // --target-error; 0 = off (double: a value beyond float's range is refused by name)
  int minSpp = 0;         // --min-spp; 0 = min(16, spp)
  std::optional<int> backgroundSpp;  // --background-spp (default 4); 0 = no survey
  double timeLimit = 0;   // --time-limit SECONDS; 0 = none
  bool denoise = false;   // --denoise
  std::string res = "960x540";
  std::string camera;
  int threads = 0;
  long long seed = 0;
  std::string sky = "1,1,1";
  EnvironmentArgs env;
  std::string preview;
  std::string filter = "box";
  int tileSize = 16;
  bool half = false;
  std::string compression = exrCompressionName(ExrOptions{}.compression);  // --compression
  bool noAovs = false;
  bool noAlbedo = false;  // --no-albedo
  bool quiet = false;
  std::vector<std::string> plugins;
  std::string cryptomatte = "none";
  int cryptomatteRanks = kDefaultCryptomatteRanks;
  std::string region;  // --region X0,Y0,X1,Y1; empty = the whole frame
  std::string frames;  // --frames A-B[:STEP]; empty = one image
  double checkpoint = 0;  // --checkpoint SECONDS
  bool checkpointGiven = false;
};

// One pass of a render as the command line set it up.
struct PassSetup {
  std::string layer;  // "" for a single pass given by -i/-p
  const IntegratorDescriptor* desc;
  ParamSet params;
  std::unique_ptr<Integrator> integrator;
  IntegratorNeeds needs;
};

// A --pass layer name that is refused: a layer of Obscura's own, or one a
// compositor reads as its own pass or layer (docs/exr.md "Layer names
// --pass refuses"). `prefix`: every name starting with it. Matched
// case-sensitively, as Blender's multilayer reader and Nuke match them.
struct ReservedLayerName {
  const char* name;
  bool prefix;
  const char* owner;  // completes "is reserved: ..."
};
const std::vector<ReservedLayerName>& reservedLayerNames();

// The passes of a render, the primary first: --pass (with --primary), or
// the single pass of -i/-p. Throws obscura::Error naming the option.
std::vector<PassSetup> passSetups(const RenderArgs& a);
bool anyScreenSpace(const std::vector<PassSetup>& setups);
// The widest guard band (pixels) the screen-space passes can have in a
// w x h render - each pass's guard-band, or the automatic band's cap -,
// or -1 without a screen-space pass (core/render/gbuffer.h layerGeometry),
// and how many screen-space passes share the layer loop.
struct ScreenSpaceBound {
  int band = -1;
  int passes = 0;
};
ScreenSpaceBound screenSpaceBound(const std::vector<PassSetup>& setups, int w, int h);

// The render settings of `a` (every option checked, in the order the CLI
// always checked them); throws obscura::Error naming the option.
RenderSettings renderSettings(const RenderArgs& a);

// True when `path` ends in `ext` (".exr"), ignoring case.
bool hasExtension(const std::string& path, const std::string& ext);
// Refuses, before any work, outputs that cannot be written, that overwrite
// the scene or each other, or whose extension is not the format written (an
// EXR under a .tif name: viewers and pipelines go by the name). `preview`
// may be empty. Messages name -o and --preview.
// `inputs`: the other files the render reads, as (option, path) pairs
// (renderInputs); an output equal to one is refused naming both.
void checkOutputPaths(const std::string& output, const std::string& preview, const std::string& scene,
                      const std::vector<std::pair<std::string, std::string>>& inputs = {});
// Refuses `output` (given by `option`, e.g. "-o ") when it is the scene or
// one of `inputs` (renderInputs), naming both.
void checkNotAnInput(const std::string& output, const std::string& option, const std::string& scene,
                     const std::vector<std::pair<std::string, std::string>>& inputs);
// True when a and b name the same file (by device and inode when both
// exist, else by their normalised paths).
bool samePath(const std::string& a, const std::string& b);
// The files a render reads besides the scene, as (option, path):
// --displace, --environment, the scene's external buffers, images and
// displacement maps ("SCENE images[0]": gltfExternalFiles), and integrator
// parameters whose value is an existing file (-p map=..., --pass
// L=containment:map=..., -p fit=...).
std::vector<std::pair<std::string, std::string>> renderInputs(const RenderArgs& a);

// Refuses a render whose film (and what the render keeps beside it: a
// screen-space pass's G-buffer, Cryptomatte, adaptive sums, the denoiser's
// planes, the preview's bytes) would need more memory than the system has
// available or than the --max-memory budget leaves, and holds it against the
// budget while the result lives (the scene's estimate is then checked beside
// it: docs/cli.md "Memory"). `layers`: the --pass layers; `screenSpace`:
// screenSpaceBound. Names --res.
MemoryHold holdFilmMemory(const RenderArgs& a, const RenderSettings& s, ScreenSpaceBound screenSpace, size_t layers);

// --checkpoint SECONDS (a.checkpoint) and the passes it allows, for the
// checkpoint file `file`; throws naming --checkpoint.
void checkCheckpoint(const RenderArgs& a, const RenderSettings& s, bool screenSpace, const std::string& file);
// What a --checkpoint file must match to be resumed (docs/production.md "Checkpoints"):
// the header's record of the render but for what differs between runs
// (threads, times, ray counts), the tile size and AOV switch, and the
// content (hashed) of every file the render reads: the scene, the files it
// names, the renderInputs and the plugins.
Fingerprint renderFingerprint(const RenderArgs& a, const RenderSettings& s, const ExrOptions& header);

// The EXR header of a finished render (docs/exr.md "The EXR pass").
ExrOptions renderHeader(const RenderArgs& a, const std::vector<PassSetup>& setups, const Camera& camera,
                        const RenderSettings& s, const RenderStats& stats, const Scene& scene);

}  // namespace obscura
