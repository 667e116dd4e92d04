// `import obscura`: the Python module (docs/python.md "Python"). It mirrors the
// command line: a Scene loaded with the CLI's scene options, render() with
// the CLI's render options, compare(), merge(), integrators(), load_plugin(). Every
// render goes through the same functions `obscura render` calls
// (app/render_setup.h: settings, passes, header; core render(); the EXR
// writer), so the same settings give the same channels bit for bit and the
// same file, and bad input raises obscura.Error with the CLI's message.
//
// Channels are NumPy views of the film's planes (read-only, no copy): each
// array's base is a capsule owning the result. The GIL is released while a
// scene loads and while a render runs; the render runs on a worker thread
// and the calling thread polls PyErr_CheckSignals every 50 ms, so Ctrl-C
// raises the core's cancel flag (the CLI's mechanism, app/interrupt.h) and
// then KeyboardInterrupt.
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>
#include <tbb/global_control.h>

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <exception>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <set>
#include <thread>

#include "app/options.h"
#include "app/compare.h"
#include "app/merge.h"
#include "app/render_setup.h"
#include "core/render/checkpoint.h"
#include <obscura/error.h>
#include "core/load/gltf_document.h"
#include "core/load/gltf_loader.h"
#include "core/image/image_io.h"
#include "core/render/plugin_loader.h"
#include <obscura/plugin.h>
#include "core/render/render.h"

namespace py = pybind11;
using namespace obscura;

namespace {

// --- keyword arguments ---------------------------------------------------------
// The keywords a function takes, converted as the CLI's text options are
// typed (a tuple (960, 540) becomes "960x540" for --res), so the CLI's
// parsers check them and their messages name the CLI's flags.
class Kwargs {
 public:
  // `named`: the function's named arguments, listed with the keywords in messages.
  Kwargs(std::string function, const py::kwargs& kw, std::vector<std::string> named = {})
      : function_(std::move(function)), known_(std::move(named)) {
    for (const auto& [k, v] : kw) left_[py::cast<std::string>(k)] = py::reinterpret_borrow<py::object>(v);
  }
  // The value of `name`, or nullopt when not given (or None).
  std::optional<py::object> take(const std::string& name) {
    known_.push_back(name);
    auto it = left_.find(name);
    if (it == left_.end()) return std::nullopt;
    py::object v = it->second;
    left_.erase(it);
    if (v.is_none()) return std::nullopt;
    return v;
  }
  template <class T>
  void take(const std::string& name, T& out) {
    if (auto v = take(name)) out = as<T>(name, *v);
  }
  // Text options: a str as typed, or numbers / sequences of numbers joined
  // with `sep` (Python's repr of a float reads back as the same float).
  void takeText(const std::string& name, std::string& out, const char* sep = ",") {
    if (auto v = take(name)) out = text(name, *v, sep);
  }
  void takeList(const std::string& name, std::vector<std::string>& out) {
    auto v = take(name);
    if (!v) return;
    if (py::isinstance<py::str>(*v)) {
      out = {py::cast<std::string>(*v)};
      return;
    }
    if (!py::isinstance<py::sequence>(*v)) throw Error(function_ + ": " + name + ": expected a str or a list of str");
    out.clear();
    for (const py::handle item : *v) out.push_back(text(name, py::reinterpret_borrow<py::object>(item), ","));
  }
  // Refuses a keyword no take() asked for.
  void finish() const {
    if (left_.empty()) return;
    std::string known;
    for (const std::string& k : known_) known += (known.empty() ? "" : ", ") + k;
    throw Error(function_ + ": unknown keyword argument '" + left_.begin()->first + "' (known: " + known + ")");
  }
  template <class T>
  T as(const std::string& name, const py::object& v) const {
    // bool is an int in Python: refuse True for a count, and 1 for a switch.
    if constexpr (std::is_same_v<T, bool>) {
      if (!py::isinstance<py::bool_>(v)) throw Error(function_ + ": " + name + ": expected True or False, got " + typeName(v));
    } else if constexpr (std::is_integral_v<T>) {
      if (py::isinstance<py::bool_>(v) || !py::isinstance<py::int_>(v))
        throw Error(function_ + ": " + name + ": expected an int, got " + typeName(v));
    } else if constexpr (std::is_floating_point_v<T>) {
      if (py::isinstance<py::bool_>(v) || !(py::isinstance<py::int_>(v) || py::isinstance<py::float_>(v)))
        throw Error(function_ + ": " + name + ": expected a number, got " + typeName(v));
    } else if constexpr (std::is_same_v<T, std::string>) {
      if (!py::isinstance<py::str>(v)) throw Error(function_ + ": " + name + ": expected a str, got " + typeName(v));
    }
    try {
      return py::cast<T>(v);
    } catch (const py::cast_error&) {
      throw Error(function_ + ": " + name + ": out of range: " + py::cast<std::string>(py::repr(v)));
    }
  }
  std::string text(const std::string& name, const py::object& v, const char* sep) const {
    if (py::isinstance<py::str>(v)) return py::cast<std::string>(v);
    const auto scalar = [&](const py::handle x) -> std::string {
      if (py::isinstance<py::bool_>(x) || !(py::isinstance<py::int_>(x) || py::isinstance<py::float_>(x)))
        throw Error(function_ + ": " + name + ": expected a str, a number or a tuple of numbers, got " +
                    typeName(py::reinterpret_borrow<py::object>(x)));
      return py::cast<std::string>(py::repr(x));
    };
    if (!py::isinstance<py::sequence>(v)) return scalar(v);
    std::string out;
    for (const py::handle x : v) out += (out.empty() ? "" : sep) + scalar(x);
    return out;
  }
  static std::string typeName(const py::object& v) { return py::cast<std::string>(py::type::of(v).attr("__name__")); }
  const std::string& function() const { return function_; }

 private:
  std::string function_;
  std::vector<std::string> known_;
  std::map<std::string, py::object> left_;
};

// The scene options (SceneArgs: the CLI's --subdiv ... --shutter).
// environment=, environment_rotation=, environment_strength=,
// environment_irradiance= (the CLI's --environment options).
void takeEnvironmentArgs(Kwargs& kw, EnvironmentArgs& a) {
  kw.take("environment", a.environment);
  kw.take("environment_rotation", a.rotation);
  kw.take("environment_strength", a.strength);
  kw.take("environment_irradiance", a.irradiance);
}

void takeSceneArgs(Kwargs& kw, SceneArgs& a) {
  kw.take("robust", a.robust);
  kw.take("normal_maps", a.normalMaps);
  kw.take("subdiv", a.subdiv);
  kw.take("subdiv_level", a.subdivLevel);
  kw.take("subdiv_backend", a.subdivBackend);
  kw.take("subdiv_edge", a.subdivEdge);
  kw.take("max_memory", a.maxMemoryGiB);
  kw.take("displace", a.displace);
  kw.take("displace_scale", a.displaceScale);
  kw.take("displace_midlevel", a.displaceMidlevel);
  kw.takeList("objects", a.objects);
  kw.takeText("frame", a.frame);
  kw.take("fps", a.fps);
  if (auto v = kw.take("animations")) {
    std::vector<std::string> list;
    if (py::isinstance<py::str>(*v)) {  // "a,b" as --animation takes it
      const std::string s = py::cast<std::string>(*v);
      size_t start = 0;
      while (start <= s.size()) {
        const size_t end = std::min(s.find(',', start), s.size());
        list.push_back(s.substr(start, end - start));
        start = end + 1;
      }
    } else {
      for (const py::handle x : *v) list.push_back(kw.text("animations", py::reinterpret_borrow<py::object>(x), ","));
    }
    a.animations = list;
  }
  kw.takeText("shutter", a.shutter);
}

// --- running with the GIL released, interruptible -------------------------------
// Runs `work(cancel)` on a worker thread with the GIL released. The calling
// thread wakes every 50 ms to run Python's signal handlers (only the main
// thread's do anything): on an exception (KeyboardInterrupt from Ctrl-C)
// it raises `cancel`, which the render loops poll every chunk of samples,
// waits for the worker and raises it. The worker's exceptions are rethrown.
void runInterruptible(const std::function<void(const std::atomic<bool>&)>& work) {
  std::atomic<bool> cancel{false};
  std::mutex m;
  std::condition_variable cv;
  bool done = false, interrupted = false;
  std::exception_ptr failure;
  {
    py::gil_scoped_release release;
    std::thread worker([&] {
      try {
        work(cancel);
      } catch (...) {
        failure = std::current_exception();
      }
      std::lock_guard<std::mutex> lock(m);
      done = true;
      cv.notify_one();
    });
    for (;;) {
      {
        std::unique_lock<std::mutex> lock(m);
        if (cv.wait_for(lock, std::chrono::milliseconds(50), [&] { return done; })) break;
      }
      if (interrupted) continue;
      py::gil_scoped_acquire acquire;
      if (PyErr_CheckSignals() != 0) interrupted = true, cancel.store(true);  // the exception stays set
    }
    worker.join();
  }
  if (interrupted) throw py::error_already_set();
  if (failure) std::rethrow_exception(failure);
}

// --- warnings: obscura's warning lines as Python warnings -----------------------
// Log::warn's sink (include/obscura/error.h) collects them from any thread - loads and
// renders run with the GIL released, the renders on TBB's threads - and each
// call of the module hands them to Python's `warnings` (category
// obscura.ObscuraWarning, a UserWarning) before it returns or raises, so filters,
// `-W error` and pytest.warns work as for any Python warning.
std::mutex gWarningsMutex;
std::vector<std::string> gWarnings;
PyObject* gWarningType = nullptr;

void collectWarning(const std::string& message) {
  std::lock_guard<std::mutex> lock(gWarningsMutex);
  gWarnings.push_back(message);
}

// With the GIL held. Throws error_already_set when a filter turns a warning
// into an error; the call's remaining warnings are dropped with it (they
// belong to the call that raised, not to the next one).
void deliverWarnings() {
  std::vector<std::string> pending;
  {
    std::lock_guard<std::mutex> lock(gWarningsMutex);
    pending.swap(gWarnings);
  }
  for (const std::string& m : pending)
    if (PyErr_WarnEx(gWarningType, m.c_str(), 1) != 0) throw py::error_already_set();
}

// --- Scene ----------------------------------------------------------------------
struct PyScene {
  std::string path;
  // The parsed file: with_options() builds other poses of it without
  // reading it again (as `obscura render --frames` does).
  std::shared_ptr<const SceneSource> source;
  SceneArgs args;
  // With subdiv_edge the refinement is measured from a camera at a
  // resolution (the CLI's --camera and --res): the scene keeps them, and
  // renders must use the same ones.
  std::string camera;
  int width = 960, height = 540;
  Camera loadCamera;
  std::unique_ptr<Scene> scene;
  double loadSeconds = 0;
};

// A scene from `source` (nullptr: read `path` first) with the options in kwargs.
std::shared_ptr<PyScene> buildScene(const std::string& path, std::shared_ptr<const SceneSource> source,
                                    const std::string& function, const py::kwargs& kwargs) {
  Kwargs kw(function, kwargs);
  auto s = std::make_shared<PyScene>();
  s->path = path;
  takeSceneArgs(kw, s->args);
  std::string res = "960x540";
  kw.takeText("res", res, "x");
  kw.takeText("camera", s->camera);
  kw.finish();
  parseResolution(res, s->width, s->height);
  sceneOptions(s->args);  // checked before the file is read, as the CLI does
  {
    py::gil_scoped_release release;  // loading cannot stop half-way, but other threads run
    const auto t0 = std::chrono::steady_clock::now();
    s->source = source ? std::move(source) : std::make_shared<const SceneSource>(path);
    s->scene = loadSceneAndCamera(s->args, *s->source, s->camera, s->width, s->height, s->loadCamera);
    s->loadSeconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  }
  deliverWarnings();
  return s;
}

py::tuple vec3(const Vec3& v) { return py::make_tuple(v.x, v.y, v.z); }

// --- images: a rendered film or a read EXR --------------------------------------
struct PyImage {
  virtual ~PyImage() = default;
  int width = 0, height = 0;
  std::vector<std::string> names;
  std::vector<const float*> planes;
  std::vector<HeaderAttribute> attributes;
  int index(const std::string& name) const {
    for (size_t i = 0; i < names.size(); ++i)
      if (names[i] == name) return int(i);
    return -1;
  }
};

struct PyResult : PyImage {
  Film film;
  ExrOptions header;
  RenderStats stats;
  double bvhSeconds = 0;
  std::string scenePath;
  std::vector<std::pair<std::string, std::string>> inputs;  // renderInputs: what write() must not overwrite
};

struct PyRead : PyImage {
  ExrImage image;
};

std::string channelList(const PyImage& img) {
  std::string all;
  for (const std::string& n : img.names) all += (all.empty() ? "" : ", ") + n;
  return all;
}

// A read-only H x W view of plane i; the capsule keeps the image alive.
py::array channelView(const std::shared_ptr<PyImage>& self, int i) {
  py::capsule owner(new std::shared_ptr<PyImage>(self), [](void* p) { delete static_cast<std::shared_ptr<PyImage>*>(p); });
  py::array_t<float> a({py::ssize_t(self->height), py::ssize_t(self->width)},
                       {py::ssize_t(self->width) * py::ssize_t(sizeof(float)), py::ssize_t(sizeof(float))},
                       self->planes[size_t(i)], owner);
  py::detail::array_proxy(a.ptr())->flags &= ~py::detail::npy_api::NPY_ARRAY_WRITEABLE_;
  return a;  // moved (C++20: implicit move to the base py::array)
}

py::dict channels(const std::shared_ptr<PyImage>& self) {
  py::dict d;
  for (size_t i = 0; i < self->names.size(); ++i) d[py::str(self->names[i])] = channelView(self, int(i));
  return d;
}

// name.R/G/B (or name.X/Y/Z; "" = the pass R,G,B) as one H x W x 3 array:
// the one copy, interleaving three planes.
py::array layer(const std::shared_ptr<PyImage>& self, const std::string& name) {
  const std::string prefix = name.empty() ? "" : name + ".";
  for (const char* axes : {"RGB", "XYZ"}) {
    int idx[3];
    for (int k = 0; k < 3; ++k) idx[k] = self->index(prefix + axes[k]);
    if (idx[0] < 0 || idx[1] < 0 || idx[2] < 0) continue;
    py::array_t<float> out({py::ssize_t(self->height), py::ssize_t(self->width), py::ssize_t(3)});
    float* o = out.mutable_data();
    const size_t n = size_t(self->width) * size_t(self->height);
    for (size_t p = 0; p < n; ++p)
      for (int k = 0; k < 3; ++k) o[3 * p + size_t(k)] = self->planes[size_t(idx[k])][p];
    return out;
  }
  throw Error("layer '" + name + "': no channels " + prefix + "R/G/B or " + prefix + "X/Y/Z (channels: " + channelList(*self) + ")");
}

py::dict headerDict(const std::vector<HeaderAttribute>& attrs) {
  py::dict d;
  for (const HeaderAttribute& h : attrs) {
    if (const auto* s = std::get_if<std::string>(&h.value)) d[py::str(h.name)] = *s;
    else if (const auto* i = std::get_if<int>(&h.value)) d[py::str(h.name)] = *i;
    else if (const auto* f = std::get_if<float>(&h.value)) d[py::str(h.name)] = *f;
    else {
      const auto& v = std::get<std::vector<float>>(h.value);
      py::array_t<float> m({py::ssize_t(4), py::ssize_t(4)});
      std::copy(v.begin(), v.end(), m.mutable_data());
      d[py::str(h.name)] = m;
    }
  }
  return d;
}

py::dict statsDict(const PyResult& r) {
  py::dict d;
  d["seconds"] = r.stats.seconds;
  d["bvh_seconds"] = r.bvhSeconds;
  py::dict rays;
  rays["camera"] = r.stats.rays.camera;
  rays["occlusion"] = r.stats.rays.occlusion;
  rays["closest"] = r.stats.rays.closest;
  rays["total"] = r.stats.rays.camera + r.stats.rays.occlusion + r.stats.rays.closest;
  d["rays"] = rays;
  d["mean_spp"] = r.stats.meanSpp;
  d["rounds"] = r.stats.rounds;
  d["gbuffer_seconds"] = r.stats.gbufferSeconds;
  d["screen_space_seconds"] = r.stats.screenSpaceSeconds;
  d["filter_seconds"] = r.stats.filterSeconds;
  d["denoise_seconds"] = r.stats.denoiseSeconds;
  return d;
}

// --- render ---------------------------------------------------------------------
std::shared_ptr<PyResult> renderScene(const PyScene& sc, const py::object& integrator, const py::object& params,
                                      const py::kwargs& kwargs) {
  Kwargs kw("render", kwargs, {"integrator", "params"});
  RenderArgs a;
  static_cast<SceneArgs&>(a) = sc.args;  // the scene's options, as the CLI passes them to both
  a.scene = sc.path;
  a.integratorGiven = !integrator.is_none() || !params.is_none();
  if (!integrator.is_none()) a.integrator = kw.as<std::string>("integrator", integrator);
  if (!params.is_none()) {
    if (!py::isinstance<py::dict>(params)) throw Error("render: params: expected a dict {name: value}");
    for (const auto& [k, v] : py::reinterpret_borrow<py::dict>(params)) {
      const py::object value = py::reinterpret_borrow<py::object>(v);
      const std::string text = py::isinstance<py::bool_>(value) ? (py::cast<bool>(value) ? "true" : "false")
                                                                 : kw.text("params", value, ",");
      a.params.push_back(py::cast<std::string>(py::str(k)) + "=" + text);
    }
  }
  if (auto v = kw.take("passes")) {  // {layer: "integrator[:key=value,...]"} or ["LAYER=integrator...", ...]
    if (py::isinstance<py::dict>(*v)) {
      for (const auto& [k, spec] : py::reinterpret_borrow<py::dict>(*v))
        a.passes.push_back(py::cast<std::string>(py::str(k)) + "=" + kw.as<std::string>("passes", py::reinterpret_borrow<py::object>(spec)));
    } else {
      for (const py::handle x : *v) a.passes.push_back(kw.as<std::string>("passes", py::reinterpret_borrow<py::object>(x)));
    }
  }
  kw.take("primary", a.primary);
  kw.take("spp", a.spp);
  kw.take("target_error", a.targetError);
  kw.take("min_spp", a.minSpp);
  if (auto v = kw.take("background_spp")) a.backgroundSpp = kw.as<int>("background_spp", *v);
  kw.take("time_limit", a.timeLimit);
  kw.take("denoise", a.denoise);
  // A scene refined for a view (subdiv_edge) renders that view unless told
  // otherwise (and is refused another, below).
  if (sc.args.subdivEdge > 0) a.res = std::to_string(sc.width) + "x" + std::to_string(sc.height), a.camera = sc.camera;
  kw.takeText("res", a.res, "x");
  kw.takeText("camera", a.camera);
  kw.take("threads", a.threads);
  kw.take("seed", a.seed);
  kw.takeText("sky", a.sky);
  takeEnvironmentArgs(kw, a.env);
  kw.take("filter", a.filter);
  kw.take("tile", a.tileSize);
  bool aovs = true;
  kw.take("aovs", aovs);
  a.noAovs = !aovs;
  bool albedo = true;  // albedo=False: --no-albedo
  kw.take("albedo", albedo);
  a.noAlbedo = !albedo;
  bool progress = false;
  kw.take("progress", progress);
  a.quiet = !progress;
  kw.take("cryptomatte", a.cryptomatte);
  kw.take("cryptomatte_ranks", a.cryptomatteRanks);
  kw.takeText("region", a.region);
  // --checkpoint SECONDS; the file is the CLI's OUTPUT.checkpoint, named here.
  std::string checkpointFile;
  if (auto v = kw.take("checkpoint")) a.checkpoint = kw.as<double>("checkpoint", *v), a.checkpointGiven = true;
  kw.take("checkpoint_file", checkpointFile);
  kw.finish();
  if (a.checkpointGiven != !checkpointFile.empty())
    throw Error("render: checkpoint and checkpoint_file go together (seconds between saves, and the file; the CLI's "
                "is OUTPUT.checkpoint)");

  loadPlugins({});  // OBSCURA_PLUGIN_PATH, as the CLI loads it (once per library)
  std::vector<PassSetup> setups = passSetups(a);
  RenderSettings s = renderSettings(a);
  const bool screenSpace = anyScreenSpace(setups);
  checkRegionPasses(s, screenSpace);
  // Held against --max-memory for the render: renders on several Python
  // threads share the process's budget.
  const MemoryHold film = holdFilmMemory(a, s, screenSpaceBound(setups, s.width, s.height), a.passes.size());
  Camera camera;
  if (sc.args.subdivEdge > 0) {
    // Refined for the load's camera and resolution (docs/scenes.md "Subdivision").
    if (s.width != sc.width || s.height != sc.height || a.camera != sc.camera)
      throw Error("--subdiv-edge: the scene was refined for camera '" + sc.camera + "' at " + std::to_string(sc.width) + "x" +
                  std::to_string(sc.height) + "; render with those, or load the scene with Scene(..., res=, camera=)");
    camera = sc.loadCamera;
  } else {
    camera = selectCamera(*sc.scene, a.camera, float(s.width) / float(s.height));
  }

  auto result = std::make_shared<PyResult>();
  std::vector<RenderPass> passes;
  for (const PassSetup& p : setups) passes.push_back({p.integrator.get(), p.needs, p.layer});
  // docs/production.md "Checkpoints": as the CLI, a damaged file is refused before the
  // render, one of another render once its header is known.
  std::optional<Checkpoint> checkpoint;
  if (a.checkpointGiven) {
    checkNotAnInput(checkpointFile, "checkpoint_file ", a.scene, renderInputs(a));
    checkCheckpoint(a, s, screenSpace, checkpointFile);
    checkpoint.emplace(checkpointFile, a.checkpoint);
    s.checkpoint = &*checkpoint;
    checkpoint->read();
    checkpoint->setFingerprint(renderFingerprint(a, s, renderHeader(a, setups, camera, s, result->stats, *sc.scene)));
  }
  {
    std::optional<tbb::global_control> limit;
    if (a.threads > 0) limit.emplace(tbb::global_control::max_allowed_parallelism, size_t(a.threads));
    runInterruptible([&](const std::atomic<bool>& cancel) {
      result->film = render(*sc.scene, camera, passes, s, result->stats, &cancel);
    });
  }
  // Before the checkpoint goes: a filter that makes a warning an error
  // loses this result, and the checkpoint lets the next call resume it.
  deliverWarnings();
  result->header = renderHeader(a, setups, camera, s, result->stats, *sc.scene);
  if (checkpoint) {
    if (checkpoint->runs() > 1) result->header.attributes.push_back({"obscura:checkpointRuns", checkpoint->runs()});
    checkpoint->remove();  // the image is complete (in memory): nothing left to resume
  }
  result->bvhSeconds = sc.scene->buildSeconds();
  result->scenePath = sc.path;
  result->inputs = renderInputs(a);
  Film& f = result->film;
  result->width = f.width(), result->height = f.height();
  for (int c : f.channels()) result->names.push_back(f.name(c)), result->planes.push_back(f.plane(c));
  result->attributes = result->header.attributes;
  return result;
}

void writeResult(const PyResult& r, const std::string& path, bool half, const std::string& compression,
                 const std::optional<std::string>& preview) {
  checkOutputPaths(path, preview.value_or(""), r.scenePath, r.inputs);
  ExrOptions exr = r.header;
  exr.half = half;
  exr.compression = exrCompressionFromName(compression, "--compression");
  {
    py::gil_scoped_release release;
    // The pass and its preview land together or not at all (as the CLI writes them).
    OutputSet out;
    out.addExr(path, r.film, exr);
    if (preview) out.addPreviewPng(*preview, r.film);
    out.commit();
  }
  deliverWarnings();
}

std::shared_ptr<PyImage> readExr(const std::string& path) {
  auto r = std::make_shared<PyRead>();
  {
    py::gil_scoped_release release;
    r->image = readExrImage(path);
  }
  r->width = r->image.width, r->height = r->image.height;
  r->names = r->image.names;
  for (const auto& p : r->image.planes) r->planes.push_back(p.data());
  r->attributes = r->image.attributes;
  deliverWarnings();
  return r;
}

// --- integrators, compare --------------------------------------------------------
py::list integratorList() {
  loadPlugins({});
  py::list out;
  for (const IntegratorDescriptor& d : IntegratorRegistry::instance().all()) {
    py::dict i;
    i["name"] = d.name;
    i["doc"] = d.doc;
    i["kind"] = d.kind == IntegratorKind::ScreenSpace ? "screen-space" : "ray-traced";
    py::list ps;
    for (const ParamSpec& p : d.params) {
      py::dict q;
      q["name"] = p.name;
      q["type"] = p.typeName();
      q["range"] = p.rangeText();
      q["default"] = p.defaultValue;
      q["doc"] = p.doc;
      if (!p.choices.empty()) q["choices"] = p.choices;
      ps.append(q);
    }
    i["params"] = ps;
    out.append(i);
  }
  return out;
}

// results.csv as a list of dicts, numbers as numbers (docs/compare.md "Compare").
py::list readResults(const std::string& dir) {
  py::module_ csv = py::module_::import("csv");
  py::object file = py::module_::import("builtins").attr("open")(dir + "/results.csv", "r", py::arg("newline") = "");
  py::list rows;
  for (const py::handle row : csv.attr("DictReader")(file)) {
    py::dict d;
    for (const auto& [k, v] : py::reinterpret_borrow<py::dict>(row)) {
      const std::string text = py::cast<std::string>(v);
      py::object value = py::str(text);
      const std::string key = py::cast<std::string>(k);
      if (key == "seed_mse" || key == "seed_time_s") {  // one value per seed, ';'-separated: a list
        py::list values;
        for (size_t b = 0; b < text.size();) {
          const size_t e = std::min(text.find(';', b), text.size());
          values.append(py::float_(std::strtod(text.substr(b, e - b).c_str(), nullptr)));
          b = e + 1;
        }
        value = values;
      } else if (!text.empty() && key != "key" && key != "config" && key != "integrator" && key != "params" && key != "pass") {
        char* end = nullptr;
        const double x = std::strtod(text.c_str(), &end);
        if (*end == '\0') value = text.find_first_not_of("-0123456789") == std::string::npos ? py::object(py::int_(std::stoll(text)))
                                                                                                : py::object(py::float_(x));
      } else if (text.empty() && (key == "bias2" || key == "variance" || key == "rmse_lo" || key == "rmse_hi" ||
                                  key == "time_lo" || key == "time_hi")) {  // one seed: no split, no interval
        value = py::none();
      }
      d[k] = value;
    }
    rows.append(d);
  }
  file.attr("close")();
  return rows;
}

py::list compare(const py::object& scene, const std::string& output, const py::object& configs, const py::kwargs& kwargs) {
  Kwargs kw("compare", kwargs, {"output", "configs"});
  CompareArgs a;
  if (py::isinstance<PyScene>(scene)) {
    const PyScene& sc = py::cast<const PyScene&>(scene);
    a.scene = sc.path;
    static_cast<SceneArgs&>(a) = sc.args;
  } else {
    a.scene = kw.as<std::string>("scene", scene);
    takeSceneArgs(kw, a);
  }
  a.output = output;
  if (py::isinstance<py::str>(configs)) a.configs = {py::cast<std::string>(configs)};
  else
    for (const py::handle c : configs) a.configs.push_back(kw.as<std::string>("configs", py::reinterpret_borrow<py::object>(c)));
  kw.takeText("spp", a.sppList);
  kw.take("reference", a.reference);
  kw.take("reference_spp", a.referenceSpp);
  kw.take("seeds", a.seeds);
  kw.takeText("targets", a.targets);
  kw.takeText("targets_flip", a.targetsFlip);
  kw.take("flip_ppd", a.flipPpd);
  kw.takeText("res", a.res, "x");
  kw.takeText("camera", a.camera);
  kw.take("threads", a.threads);
  kw.take("seed", a.seed);
  kw.takeText("sky", a.sky);
  takeEnvironmentArgs(kw, a.env);
  bool progress = false;
  kw.take("progress", progress);
  a.quiet = !progress;
  kw.finish();
  loadPlugins({});
  int code = 0;
  runInterruptible([&](const std::atomic<bool>& cancel) { code = runCompare(a, &cancel); });
  if (code != 0) throw Error("compare: stopped with exit code " + std::to_string(code));
  deliverWarnings();
  return readResults(output);
}

}  // namespace

PYBIND11_MODULE(obscura, m) {
  m.doc() = "Obscura: film-style ambient passes (AO, obscurance, ambient transfer, GI) from glTF scenes (docs/python.md \"Python\")";
  m.attr("__version__") = OBSCURA_VERSION;
  // The built-in integrators are linked into this library, not into python3.
  static const int anchor = 0;
  setBuiltinModule(&anchor);
  // Messages name the CLI's flags ("--spp must be at least 1"), the same
  // line `obscura` prints.
  nameSettingsAsFlags();
  static py::exception<Error> error(m, "Error");
  // Not named Warning: `from obscura import *` would hide the built-in.
  gWarningType = PyErr_NewExceptionWithDoc("obscura.ObscuraWarning",
                                           "A warning obscura prints as `obscura: warning: ...` on the CLI",
                                           PyExc_UserWarning, nullptr);
  if (!gWarningType) throw py::error_already_set();
  m.attr("ObscuraWarning") = py::reinterpret_borrow<py::object>(gWarningType);
  Log::setWarningSink(collectWarning);
  py::register_exception_translator([](std::exception_ptr p) {
    // The warnings of the failed call first (a filter that makes one an
    // error does not replace the call's own error).
    try {
      deliverWarnings();
    } catch (const py::error_already_set&) {
      PyErr_Clear();
    }
    try {
      if (p) std::rethrow_exception(p);
    } catch (const Error& e) {
      PyErr_SetString(error.ptr(), e.what());
    } catch (const std::bad_alloc&) {
      PyErr_SetString(error.ptr(), "out of memory");
    }
  });

  py::class_<PyScene, std::shared_ptr<PyScene>>(m, "Scene",
                                                "A scene loaded once (BVH built) and rendered any number of times")
      .def(py::init([](const std::string& path, const py::kwargs& kw) { return buildScene(path, nullptr, "Scene", kw); }),
           py::arg("path"),
           "Scene(path, **options): options as the CLI's scene options (robust, normal_maps, subdiv, subdiv_level, subdiv_backend, "
           "subdiv_edge, max_memory, displace, displace_scale, displace_midlevel, objects, frame, fps, animations, "
           "shutter; res and camera for subdiv_edge)")
      .def("with_options",
           [](const PyScene& s, const py::kwargs& kw) { return buildScene(s.path, s.source, "with_options", kw); },
           "The same file (not read again) built with other options (e.g. frame=12): a new Scene")
      .def_readonly("path", &PyScene::path)
      .def_property_readonly("materials",
                             [](const PyScene& s) {
                               std::vector<std::string> names;
                               for (const Material& m : s.scene->materials) names.push_back(m.name);
                               return names;
                             })
      .def_property_readonly("animations",
                             [](const PyScene& s) {
                               py::list out;
                               if (const GltfDocument* doc = s.source->document())
                                 for (const GltfDocument::AnimationInfo& a : doc->animations()) {
                                   py::dict d;
                                   d["name"] = a.name;
                                   d["start"] = a.start;
                                   d["end"] = a.end;
                                   d["channels"] = a.channels;
                                   out.append(d);
                                 }
                               return out;
                             })
      .def_property_readonly("triangles", [](const PyScene& s) { return s.scene->stats().renderedTriangles; })
      .def_property_readonly("unique_triangles", [](const PyScene& s) { return s.scene->stats().uniqueTriangles; })
      .def_property_readonly("meshes", [](const PyScene& s) { return s.scene->stats().meshes; })
      .def_property_readonly("instances", [](const PyScene& s) { return s.scene->stats().instances; })
      .def_property_readonly("cameras",
                             [](const PyScene& s) {
                               py::list out;
                               for (const Camera& c : s.scene->cameras) {
                                 py::dict d;
                                 d["name"] = c.name;
                                 d["index"] = c.fileIndex;
                                 d["yfov"] = c.yfov;
                                 d["position"] = vec3(c.position());
                                 d["animated"] = c.animated;
                                 out.append(d);
                               }
                               return out;
                             })
      .def_property_readonly("objects",
                             [](const PyScene& s) {
                               py::list out;
                               for (const SceneObject& o : s.scene->objects) {
                                 py::dict d;
                                 d["name"] = o.name;
                                 d["roles"] = o.roles.isDefault() ? std::string("default") : o.roles.describe();
                                 out.append(d);
                               }
                               return out;
                             })
      .def_property_readonly("bounds",
                             [](const PyScene& s) -> py::object {
                               const Bounds3& b = s.scene->bounds();
                               if (b.empty()) return py::none();
                               return py::make_tuple(vec3(b.lo), vec3(b.hi));
                             })
      .def_property_readonly("bvh_seconds", [](const PyScene& s) { return s.scene->buildSeconds(); })
      .def_readonly("load_seconds", &PyScene::loadSeconds)
      .def("__repr__", [](const PyScene& s) {
        return "<obscura.Scene '" + s.path + "': " + std::to_string(s.scene->stats().renderedTriangles) + " triangles>";
      });

  py::class_<PyImage, std::shared_ptr<PyImage>>(m, "Image", "Channels (NumPy float32, H x W) and header of a pass")
      .def_readonly("width", &PyImage::width)
      .def_readonly("height", &PyImage::height)
      .def_readonly("channel_names", &PyImage::names)
      .def_property_readonly("channels", &channels)
      .def_property_readonly("header", [](const PyImage& i) { return headerDict(i.attributes); })
      .def_property_readonly("rgb", [](const std::shared_ptr<PyImage>& i) { return layer(i, ""); })
      .def("layer", &layer, py::arg("name"))
      .def("__getitem__",
           [](const std::shared_ptr<PyImage>& self, const std::string& name) {
             const int i = self->index(name);
             if (i < 0) throw py::key_error("no channel '" + name + "' (channels: " + channelList(*self) + ")");
             return channelView(self, i);
           })
      .def("__contains__", [](const PyImage& self, const std::string& name) { return self.index(name) >= 0; });

  py::class_<PyResult, PyImage, std::shared_ptr<PyResult>>(m, "Result", "A render: its channels, header and stats")
      .def_property_readonly("stats", &statsDict)
      .def("write", &writeResult, py::arg("path"), py::kw_only(), py::arg("half") = false, py::arg("compression") = "zip",
           py::arg("preview") = py::none(), "Writes the EXR `obscura render -o PATH` writes (and a --preview PNG)");

  m.def("render", &renderScene, py::arg("scene"), py::arg("integrator") = py::none(), py::arg("params") = py::none(),
        "render(scene, integrator='ao', params={...}, **options): options as `obscura render`'s (docs/python.md \"Python\")");
  m.def("read_exr", &readExr, py::arg("path"), "Every channel and the header of an EXR (an Image)");
  m.def("integrators", &integratorList, "The registered integrators with their parameters");
  m.def("load_plugin",
        [](const std::string& path) {
          loadPlugin(path);
          deliverWarnings();
        },
        py::arg("path"),
        "Loads an integrator plugin (shared library), as --plugin");
  m.def("merge",
        [](const std::string& output, const std::vector<std::string>& tiles) {
          {
            py::gil_scoped_release release;
            mergeRegions(output, tiles);
          }
          deliverWarnings();
        },
        py::arg("output"), py::arg("tiles"), "`obscura merge`: region renders assembled into the full frame");
  m.def("compare", &compare, py::arg("scene"), py::arg("output"), py::arg("configs"),
        "compare(scene, output_dir, configs, **options): `obscura compare`; returns results.csv's rows");
}
