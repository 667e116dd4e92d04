#include "app/render_setup.h"
#include "core/util/input_file.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <cctype>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <map>
#include <mutex>
#include <sstream>
#include <variant>

#include <sys/stat.h>

#include "app/exr_header.h"
#include "core/load/gltf_document.h"
#include "core/render/adaptive.h"
#include "core/render/gbuffer.h"
#include "core/render/pixel_sums.h"
#include <obscura/error.h>

namespace obscura {

namespace {

// A layer name: a letter, then letters, digits or '_'; not a layer the film
// writes itself nor one a compositor takes for its own (reservedLayerNames).
void checkLayerName(const std::string& layer, const std::string& text) {
  const bool ok = !layer.empty() && std::isalpha(static_cast<unsigned char>(layer[0])) &&
                  layer.find_first_not_of("abcdefghijklmnopqrstuvwxyzABCDEFGHIJKLMNOPQRSTUVWXYZ0123456789_") == std::string::npos;
  if (!ok) throw Error("--pass '" + text + "': the layer name '" + layer + "' must be a letter followed by letters, digits or '_'");
  for (const ReservedLayerName& r : reservedLayerNames())
    if (r.prefix ? layer.rfind(r.name, 0) == 0 : layer == r.name)
      throw Error("--pass '" + text + "': the layer name '" + layer + "' is reserved: " + r.owner +
                  (r.prefix ? " (every name starting '" + std::string(r.name) + "')" : std::string()) +
                  "; docs/exr.md \"Layer names --pass refuses\" lists them");
}

// The passes of a render, the primary first: --pass (with --primary), or

// A file's content as FNV-1a 64 in hex with its size ("unreadable" if it
// cannot be read). Hashed once per process while its device, inode, size
// and modification time stay the same: --frames and the Python module
// fingerprint every render, and a buffer or map can be large.
std::string fileHash(const std::string& path) {
  checkInputFile(path);  // a FIFO or a device: refused by name, never read
  struct stat st {};
  if (::stat(path.c_str(), &st) != 0 || !S_ISREG(st.st_mode)) return "unreadable";
  const std::string key = std::to_string(st.st_dev) + ":" + std::to_string(st.st_ino) + ":" + std::to_string(st.st_size) +
                          ":" + std::to_string(st.st_mtim.tv_sec) + "." + std::to_string(st.st_mtim.tv_nsec);
  static std::mutex mutex;
  static std::map<std::string, std::string> known;
  {
    const std::lock_guard<std::mutex> lock(mutex);
    if (auto it = known.find(key); it != known.end()) return it->second;
  }
  std::ifstream in(path, std::ios::binary);
  if (!in) return "unreadable";
  // FNV-1a over 8-byte words (bytes for the tail): a byte-wise loop waits
  // on one multiply per byte, 0.24 GB/s against 0.63 here (256 MB, a
  // loaded 2-core machine). Each step is a bijection of the state, so any
  // one changed word changes the result.
  uint64_t h = 0xcbf29ce484222325ull, size = 0;
  std::vector<char> buf(1 << 20);
  while (in) {
    in.read(buf.data(), std::streamsize(buf.size()));
    const size_t n = size_t(in.gcount());
    size_t i = 0;
    for (uint64_t w; i + 8 <= n; i += 8) std::memcpy(&w, buf.data() + i, 8), h = (h ^ w) * 0x100000001b3ull;
    for (; i < n; ++i) h = (h ^ (unsigned char)buf[i]) * 0x100000001b3ull;
    size += n;
  }
  if (in.bad()) return "unreadable";
  char text[64];
  std::snprintf(text, sizeof text, "%016llx, %llu bytes", (unsigned long long)h, (unsigned long long)size);
  const std::lock_guard<std::mutex> lock(mutex);
  return known[key] = text;
}

// A header value as text, floats exactly (hex).
std::string attributeText(const HeaderAttribute& h) {
  const auto hex = [](float f) {
    char t[32];
    std::snprintf(t, sizeof t, "%a", double(f));
    return std::string(t);
  };
  if (const auto* v = std::get_if<std::string>(&h.value)) return *v;
  if (const auto* v = std::get_if<int>(&h.value)) return std::to_string(*v);
  if (const auto* v = std::get_if<float>(&h.value)) return hex(*v);
  std::string all;
  for (float f : std::get<std::vector<float>>(h.value)) all += (all.empty() ? "" : ",") + hex(f);
  return all;
}

}  // namespace

const std::vector<ReservedLayerName>& reservedLayerNames() {
  // Why each is refused (issue #37, checked in Blender 3.4's compositor):
  // Blender's multilayer reader files a channel LAYER.C under the pass
  // LAYER, and the bare R,G,B,A under "Combined" and Z under "Depth", so a
  // layer named Combined put six colour channels in one pass and crashed
  // Blender, and Depth or Alpha mixed into the passes and sockets it makes
  // itself. Its other render-pass names would be read as those passes. Nuke
  // merges a layer named like one of its built-in layers into that layer.
  static const char* const obscura = "a layer Obscura writes itself";
  static const char* const blender = "a render pass name of Blender's compositor";
  static const char* const nuke = "a built-in layer of Nuke";
  static const std::vector<ReservedLayerName> names = {
      {"R", false, obscura}, {"G", false, obscura}, {"B", false, obscura}, {"A", false, obscura},
      {"Z", false, obscura}, {"N", false, obscura}, {"albedo", false, obscura}, {"shaded", false, obscura},
      {"lighting", false, obscura}, {"noisy", false, obscura}, {"W_error", false, obscura}, {"spp", false, obscura},
      {"Crypto", true, "Cryptomatte's layers"},
      {"Combined", false, blender}, {"Alpha", false, blender}, {"Depth", false, blender}, {"Mist", false, blender},
      {"Normal", false, blender}, {"Position", false, blender}, {"Vector", false, blender}, {"UV", false, blender},
      {"Emit", false, blender}, {"Env", false, blender}, {"AO", false, blender}, {"Shadow", false, blender},
      {"IndexOB", false, blender}, {"IndexMA", false, blender}, {"DiffDir", false, blender},
      {"DiffInd", false, blender}, {"DiffCol", false, blender}, {"GlossDir", false, blender},
      {"GlossInd", false, blender}, {"GlossCol", false, blender}, {"TransDir", false, blender},
      {"TransInd", false, blender}, {"TransCol", false, blender}, {"SubsurfaceDir", false, blender},
      {"SubsurfaceInd", false, blender}, {"SubsurfaceCol", false, blender}, {"VolumeDir", false, blender},
      {"VolumeInd", false, blender}, {"Freestyle", false, blender}, {"BloomCol", false, blender},
      {"Noisy", true, blender}, {"Denoising", true, blender}, {"Debug", true, blender},
      {"rgba", false, nuke}, {"rgb", false, nuke}, {"alpha", false, nuke}, {"depth", false, nuke},
      {"motion", false, nuke}, {"forward", false, nuke}, {"backward", false, nuke}, {"mask", false, nuke},
      {"rotopaint_mask", false, nuke}, {"deep", false, nuke},
  };
  return names;
}

// True when a and b name the same file (existing or not).
bool samePath(const std::string& a, const std::string& b) {
  namespace fs = std::filesystem;
  std::error_code ea, eb;
  if (fs::exists(a, ea) && fs::exists(b, eb)) return fs::equivalent(a, b, ea);
  return fs::weakly_canonical(a, ea) == fs::weakly_canonical(b, eb);
}

// True when `path` ends in `ext` (".exr"), ignoring case.
std::vector<std::pair<std::string, std::string>> renderInputs(const RenderArgs& a) {
  std::vector<std::pair<std::string, std::string>> in = {{"--displace", a.displace}, {"--environment", a.env.environment}};
  // The files the scene names: a .gltf's external buffers and images, its
  // displacement maps (an OBJ's material libraries are not read for pixels:
  // core/load/obj_loader.h).
  if (!hasExtension(a.scene, ".obj"))
    for (auto& [field, path] : gltfExternalFiles(a.scene)) in.push_back({a.scene + " " + field, std::move(path)});
  // Integrator parameters naming files (containment's and ssat's map=,
  // multibounce's fit=): any value that is an existing file.
  const auto params = [&](const std::string& option, const std::vector<std::string>& assignments) {
    for (const std::string& p : assignments) {
      const size_t eq = p.find('=');
      std::error_code ec;
      if (eq != std::string::npos && std::filesystem::is_regular_file(p.substr(eq + 1), ec))
        in.push_back({option + p.substr(0, eq) + "=", p.substr(eq + 1)});
    }
  };
  params("-p ", a.params);
  for (const std::string& text : a.passes) {
    const size_t colon = text.find(':');
    if (colon == std::string::npos) continue;
    std::vector<std::string> assignments;
    std::stringstream list(text.substr(colon + 1));
    for (std::string item; std::getline(list, item, ',');) assignments.push_back(item);
    params("--pass " + text.substr(0, text.find('=')) + ":", assignments);
  }
  return in;
}

bool hasExtension(const std::string& path, const std::string& ext) {
  if (path.size() < ext.size()) return false;
  for (size_t i = 0; i < ext.size(); ++i)
    if (std::tolower((unsigned char)path[path.size() - ext.size() + i]) != ext[i]) return false;
  return true;
}

void checkNotAnInput(const std::string& output, const std::string& option, const std::string& scene,
                     const std::vector<std::pair<std::string, std::string>>& inputs) {
  if (samePath(output, scene)) throw Error(option + output + ": is the scene file; refusing to overwrite it");
  for (const auto& [what, input] : inputs)
    if (!input.empty() && samePath(output, input))
      throw Error(option + output + ": is the same file as " + what + " " + input + "; refusing to overwrite an input");
}

void checkOutputPaths(const std::string& output, const std::string& preview, const std::string& scene,
                      const std::vector<std::pair<std::string, std::string>>& inputs) {
  checkOutputName(output, "-o ");
  if (!preview.empty()) checkOutputName(preview, "--preview ");
  checkWritable(output);
  checkNotAnInput(output, "-o ", scene, inputs);
  if (!preview.empty()) {
    checkWritable(preview);
    if (samePath(preview, output)) throw Error("--preview " + preview + ": is the same file as -o");
    checkNotAnInput(preview, "--preview ", scene, inputs);
  }
  // After the checks above, whose messages say more about such a path.
  if (!hasExtension(output, ".exr")) throw Error("-o " + output + ": must end in .exr (the pass is written as OpenEXR)");
  if (!preview.empty() && !hasExtension(preview, ".png"))
    throw Error("--preview " + preview + ": must end in .png (the preview is written as PNG)");
}

std::vector<PassSetup> passSetups(const RenderArgs& a) {
  std::vector<PassSetup> out;
  const auto add = [&](std::string layer, const std::string& integrator, const std::vector<std::string>& assignments) {
    const IntegratorDescriptor& desc = IntegratorRegistry::instance().find(integrator);
    ParamSet params(desc.params, desc.name);
    for (const auto& p : assignments) params.setAssignment(p);
    auto integ = desc.create(params);
    const IntegratorNeeds needs = passNeeds(desc, params);
    out.push_back({std::move(layer), &desc, std::move(params), std::move(integ), needs});
  };
  if (a.passes.empty()) {
    if (!a.primary.empty()) throw Error("--primary: names a --pass layer, but no --pass was given");
    add("", a.integrator, a.params);
    return out;
  }
  if (a.integratorGiven) throw Error("--pass: replaces -i and -p (give each pass its integrator and parameters)");
  for (const std::string& text : a.passes) {
    const size_t eq = text.find('=');
    if (eq == std::string::npos) throw Error("--pass '" + text + "': expected LAYER=integrator[:key=value,...]");
    const std::string layer = text.substr(0, eq);
    checkLayerName(layer, text);
    for (const PassSetup& p : out)
      if (p.layer == layer) throw Error("--pass '" + text + "': layer '" + layer + "' is already a pass");
    const IntegratorSpec spec = parseIntegratorSpec("--pass", text.substr(eq + 1));
    add(layer, spec.integrator, spec.assignments);
  }
  if (!a.primary.empty()) {
    auto it = std::find_if(out.begin(), out.end(), [&](const PassSetup& p) { return p.layer == a.primary; });
    if (it == out.end()) throw Error("--primary: no --pass has the layer '" + a.primary + "'");
    std::rotate(out.begin(), it, it + 1);
  }
  return out;
}


bool anyScreenSpace(const std::vector<PassSetup>& setups) {
  return std::any_of(setups.begin(), setups.end(), [](const PassSetup& p) { return p.desc->kind == IntegratorKind::ScreenSpace; });
}

ScreenSpaceBound screenSpaceBound(const std::vector<PassSetup>& setups, int w, int h) {
  ScreenSpaceBound bound;
  for (const PassSetup& p : setups) {
    const ScreenSpaceIntegrator* ss = p.integrator->screenSpace();
    if (!ss) continue;
    const ScreenSpaceIntegrator::GuardBand gb = ss->guardBand();
    // (The blur's radius widens the layer like the band: layerGeometry.)
    bound.band = std::max(bound.band, (gb.pixels >= 0 ? gb.pixels : guardBandCap(w, h)) + std::max(0, ss->blur().radius));
    ++bound.passes;
  }
  return bound;
}

RenderSettings renderSettings(const RenderArgs& args) {
  RenderSettings s;
  parseResolution(args.res, s.width, s.height);
  if (args.spp < 1) throw Error("--spp: must be at least 1, got " + std::to_string(args.spp));
  checkThreads(args.threads);
  if (args.tileSize < 1 || args.tileSize > 4096) throw Error("--tile: must be in [1, 4096], got " + std::to_string(args.tileSize));
  if (args.seed < 0 || args.seed > 0xffffffffLL) throw Error("--seed: must be in [0, 4294967295]");
  if (args.filter == "box") s.filter = PixelFilter::Box;
  else if (args.filter == "gaussian") s.filter = PixelFilter::Gaussian;
  else throw Error("--filter: expected box or gaussian, got '" + args.filter + "'");
  s.spp = args.spp;
  // Read as a double so that a value beyond float's range is named as such
  // (converted first, 1e300 became inf and was reported as "not finite").
  if (args.targetError > double(std::numeric_limits<float>::max()))
    throw Error("--target-error: " + formatFloat(args.targetError) + " is above the largest standard error a pass holds (" +
                formatFloat(double(std::numeric_limits<float>::max())) + ")");
  s.targetError = float(args.targetError);
  s.minSpp = args.minSpp;
  if (args.backgroundSpp) {
    // As --min-spp: a setting that would change nothing is refused.
    if (!(args.targetError > 0.0f))
      throw Error("--background-spp needs --target-error (without a target every pixel takes --min-spp or more)");
    s.backgroundSpp = *args.backgroundSpp;
  }
  s.timeLimit = args.timeLimit;
  s.denoise = args.denoise;
  if (s.denoise && args.noAovs) throw Error("--denoise: the denoiser is guided by the AOVs (N, Z, W_error); drop --no-aovs");
  checkAdaptiveSettings(s);
  s.seed = uint32_t(args.seed);
  s.threads = args.threads;
  s.tileSize = args.tileSize;
  s.sky = parseSky(args.sky);
  s.environment = loadEnvironment(args.env, args.sky);
  s.aovs = !args.noAovs;
  if (args.noAlbedo && args.noAovs) throw Error("--no-albedo: --no-aovs already drops every AOV; give one of them");
  s.albedoAov = !args.noAlbedo;
  s.progress = !args.quiet;
  s.cryptomatte = parseCryptomatte(args.cryptomatte, args.cryptomatteRanks);
  s.motionBlur = !args.shutter.empty();
  if (!args.region.empty()) {
    s.region = parseRegion(args.region);
    checkRegion(s.region, s.width, s.height);
  }
  return s;
}

MemoryHold holdFilmMemory(const RenderArgs& a, const RenderSettings& s, ScreenSpaceBound screenSpace, size_t layers) {
  // The film's planes, plus the preview's bytes; the EXR is written from the
  // planes a band at a time, so it needs no second copy.
  // A screen-space integrator also keeps whole-image state (a G-buffer
  // layer, the pixel sums, the estimates: core/render/gbuffer.h), for
  // the whole frame: a capped band makes even a region's layer the
  // whole image's (LayerGeometry::readsImage).
  // Each layer adds three planes.
  // A --region film holds the region only.
  const PixelRect win = renderWindow(s);
  const uint64_t need = filmBytes(win.width(), win.height(), s.aovs, s.albedoAov) + uint64_t(layers) * 3 * sizeof(float) * win.size() +
                        (a.preview.empty() ? 0 : uint64_t(win.size()) * 3) +
                        (screenSpace.band >= 0 ? screenSpaceWorkingBytes(PixelRect{0, 0, s.width, s.height}, screenSpace.band,
                                                                          screenSpace.passes)
                                               : 0) +
                        cryptomatteBytes(s.cryptomatte, win.width(), win.height()) +
                        // Adaptive sampling keeps every pixel's sums across rounds (core/render/render.cpp);
                        // the denoiser about 24 floats per pixel (noisy.R/G/B, its guides and
                        // working planes: core/image/denoise.cpp).
                        (adaptiveSampling(s) ? uint64_t(win.size()) * (sizeof(PixelSums) + sizeof(HalfSums) +
                                                                       uint64_t(layers) * sizeof(PassSums))
                                             : 0) +
                        (s.denoise ? uint64_t(win.size()) * 24 * sizeof(float) : 0);
  const uint64_t avail = availableMemoryBytes();
  if (avail > 0 && need > avail) {
    char msg[160];
    std::snprintf(msg, sizeof msg, "the film needs %.1f GiB, but only %.1f GiB of memory is available", double(need) / (1 << 30),
                  double(avail) / (1 << 30));
    throw Error("--res " + a.res + ": " + msg);
  }
  return MemoryHold(need, "--res " + a.res + ": the film");
}

void checkCheckpoint(const RenderArgs& a, const RenderSettings& s, bool screenSpace, const std::string& file) {
  if (!(a.checkpoint >= 0) || !std::isfinite(a.checkpoint))
    throw Error("--checkpoint: expected seconds >= 0 (0: after every tile), got " + formatFloat(a.checkpoint));
  // The checkpoint's own temporary is FILE.tmp.
  checkOutputName(file + ".tmp", "--checkpoint: ", 0);
  RenderSettings cs = s;
  Checkpoint probe(file, a.checkpoint);
  probe.checkPath();
  cs.checkpoint = &probe;
  checkCheckpointPasses(cs, screenSpace);
}

Fingerprint renderFingerprint(const RenderArgs& a, const RenderSettings& s, const ExrOptions& header) {
  // The switches whose effect spreads over many header attributes first, so
  // that a refusal names them rather than one of their consequences.
  Fingerprint fp = {{"tile size", std::to_string(s.tileSize)}, {"AOVs", !s.aovs ? "off" : s.albedoAov ? "on" : "on, no albedo"}};
  fp.emplace_back("scene file", fileHash(a.scene));
  // Every other file that decides pixels, by content: the scene's buffers,
  // images and displacement maps, --displace, integrator parameters naming
  // files (map=, fit=). A map replaced between a kill and the resume would
  // otherwise make an image half of each. --environment is in the header
  // already (obscura:environmentHash, of the decoded pixels). Before the
  // header's values, which a changed file changes too (the automatic
  // camera frames the displaced bounds): a refusal names the file.
  for (const auto& [option, path] : renderInputs(a))
    if (!path.empty() && option != "--environment")
      fp.emplace_back((option.back() == '=' ? option : option + " ") + path, fileHash(path));
  for (const HeaderAttribute& h : header.attributes) {
    const std::string& n = h.name;
    if (isRunAttribute(n)) continue;
    fp.emplace_back(n, attributeText(h));
  }
  const char* env = std::getenv("OBSCURA_PLUGIN_PATH");
  fp.emplace_back("OBSCURA_PLUGIN_PATH", env ? env : "");
  for (const std::string& p : a.plugins) fp.emplace_back("--plugin " + p, fileHash(p));
  return fp;
}

ExrOptions renderHeader(const RenderArgs& a, const std::vector<PassSetup>& setups, const Camera& camera,
                        const RenderSettings& s, const RenderStats& stats, const Scene& scene) {
  std::vector<LayerInfo> layers;
  if (!a.passes.empty())
    for (const PassSetup& p : setups) layers.push_back({p.layer, p.desc, &p.params});
  return passHeader(PassInfo{.scenePath = a.scene, .camera = camera, .integrator = *setups.front().desc,
                             .params = setups.front().params, .settings = s, .stats = stats, .filterName = a.filter,
                             .robust = a.robust, .sceneArgs = &a, .scene = &scene, .bvhSeconds = scene.buildSeconds(),
                             .layers = layers});
}

}  // namespace obscura
