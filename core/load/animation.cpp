#include "core/load/animation.h"

#include <tiny_gltf.h>

#include <algorithm>
#include <cmath>
#include <set>

#include <obscura/error.h>
#include "core/load/gltf_document.h"
#include <obscura/params.h>
#include "core/util/option_names.h"

namespace obscura {

std::array<double, 4> slerp(const std::array<double, 4>& a, const std::array<double, 4>& bIn, double u) {
  double d = a[0] * bIn[0] + a[1] * bIn[1] + a[2] * bIn[2] + a[3] * bIn[3];
  // q and -q are the same rotation: take the one on a's side, the shorter arc.
  std::array<double, 4> b = bIn;
  if (d < 0) {
    for (double& x : b) x = -x;
    d = -d;
  }
  double wa, wb;
  if (d > 1.0 - 1e-9) {
    // sin(theta) ~ 0: the arc is a straight line to double precision.
    wa = 1.0 - u, wb = u;
  } else {
    const double theta = std::acos(d), s = std::sin(theta);
    wa = std::sin((1.0 - u) * theta) / s;
    wb = std::sin(u * theta) / s;
  }
  std::array<double, 4> r;
  for (size_t i = 0; i < 4; ++i) r[i] = wa * a[i] + wb * b[i];
  const double len = std::sqrt(r[0] * r[0] + r[1] * r[1] + r[2] * r[2] + r[3] * r[3]);
  for (double& x : r) x /= len;
  return r;
}

void AnimationSampler::evaluate(double seconds, double* out) const {
  const size_t n = size_t(components), keys = times.size();
  // A key's value: LINEAR/STEP store values only; CUBICSPLINE stores
  // (in-tangent, value, out-tangent) per key.
  const auto value = [&](size_t k) { return values.data() + (interpolation == Interpolation::CubicSpline ? (3 * k + 1) * n : k * n); };
  const auto copy = [&](const double* v) { std::copy(v, v + n, out); };
  // Before the first key and after the last the end value holds.
  if (!(seconds > times.front())) return copy(value(0));
  if (seconds >= times.back()) return copy(value(keys - 1));
  // The interval [t_k, t_k+1) holding the time.
  const size_t k = size_t(std::upper_bound(times.begin(), times.end(), seconds) - times.begin()) - 1;
  const double t0 = times[k], t1 = times[k + 1], dt = t1 - t0;
  const double u = (seconds - t0) / dt;
  switch (interpolation) {
    case Interpolation::Step: return copy(value(k));
    case Interpolation::Linear: {
      const double *a = value(k), *b = value(k + 1);
      if (rotation) {
        const std::array<double, 4> q = slerp({a[0], a[1], a[2], a[3]}, {b[0], b[1], b[2], b[3]}, u);
        return copy(q.data());
      }
      for (size_t c = 0; c < n; ++c) out[c] = a[c] + (b[c] - a[c]) * u;
      return;
    }
    case Interpolation::CubicSpline: {
      // Hermite basis (spec Appendix C): p(u) = (2u^3 - 3u^2 + 1) v_k +
      // (u^3 - 2u^2 + u) dt b_k + (-2u^3 + 3u^2) v_k+1 + (u^3 - u^2) dt a_k+1.
      const double u2 = u * u, u3 = u2 * u;
      const double h00 = 2 * u3 - 3 * u2 + 1, h10 = u3 - 2 * u2 + u, h01 = -2 * u3 + 3 * u2, h11 = u3 - u2;
      const double* vk = value(k);
      const double* bk = vk + n;               // out-tangent of key k
      const double* vk1 = value(k + 1);
      const double* ak1 = vk1 - n;             // in-tangent of key k+1
      for (size_t c = 0; c < n; ++c) out[c] = h00 * vk[c] + h10 * dt * bk[c] + h01 * vk1[c] + h11 * dt * ak1[c];
      if (rotation) {
        const double len = std::sqrt(out[0] * out[0] + out[1] * out[1] + out[2] * out[2] + out[3] * out[3]);
        if (len > 0 && std::isfinite(len))
          for (size_t c = 0; c < 4; ++c) out[c] /= len;
      }
      return;
    }
  }
}

std::vector<Animation> readAnimations(const GltfDocument& doc) {
  const tinygltf::Model& model = doc.model();
  std::vector<Animation> out;
  for (size_t ai = 0; ai < model.animations.size(); ++ai) {
    const tinygltf::Animation& ga = model.animations[ai];
    const std::string af = "animations[" + std::to_string(ai) + "]";
    Animation anim;
    anim.name = ga.name;
    anim.fileChannels = ga.channels.size();

    // Every sampler's keyframe times, checked whether or not a channel uses
    // it: a file with a broken sampler is broken.
    std::vector<std::vector<double>> times(ga.samplers.size());
    for (size_t si = 0; si < ga.samplers.size(); ++si) {
      const tinygltf::AnimationSampler& gs = ga.samplers[si];
      const std::string sf = af + ".samplers[" + std::to_string(si) + "]";
      if (gs.interpolation != "LINEAR" && gs.interpolation != "STEP" && gs.interpolation != "CUBICSPLINE")
        doc.fail(sf + ".interpolation", "expected LINEAR, STEP or CUBICSPLINE, got '" + gs.interpolation + "'");
      const std::string inf = sf + ".input";
      if (gs.input < 0 || size_t(gs.input) >= model.accessors.size())
        doc.fail(inf, "accessor " + std::to_string(gs.input) + " does not exist");
      const tinygltf::Accessor& acc = model.accessors[size_t(gs.input)];
      if (acc.type != TINYGLTF_TYPE_SCALAR || acc.componentType != TINYGLTF_COMPONENT_TYPE_FLOAT)
        doc.fail(inf, "keyframe times must be a float SCALAR accessor (accessors[" + std::to_string(gs.input) + "])");
      const std::vector<float> t = doc.readFloats(gs.input, inf, 1);
      if (t.empty()) doc.fail(inf, "no keyframes (count 0)");
      for (size_t k = 1; k < t.size(); ++k)
        if (!(t[k] > t[k - 1]))
          doc.fail(inf, "keyframe times must be strictly increasing: element " + std::to_string(k) + " (" +
                            formatFloat(t[k]) + ") follows " + formatFloat(t[k - 1]));
      if (gs.interpolation == "CUBICSPLINE" && t.size() < 2)
        doc.fail(inf, "a CUBICSPLINE sampler needs at least 2 keyframes");
      times[si].assign(t.begin(), t.end());
    }

    std::set<std::pair<int, std::string>> targets;  // (node, path): each at most once per animation
    bool anyKey = false;
    for (size_t ci = 0; ci < ga.channels.size(); ++ci) {
      const tinygltf::AnimationChannel& gc = ga.channels[ci];
      const std::string cf = af + ".channels[" + std::to_string(ci) + "]";
      if (gc.sampler < 0 || size_t(gc.sampler) >= ga.samplers.size())
        doc.fail(cf + ".sampler", "sampler " + std::to_string(gc.sampler) + " does not exist (the animation has " +
                                      std::to_string(ga.samplers.size()) + ")");
      const std::string& path = gc.target_path;
      if (path == "weights") {
        doc.warn("morph target animation is not supported (ignored)");
        continue;
      }
      if (path != "translation" && path != "rotation" && path != "scale") {
        if (path.empty()) doc.fail(cf + ".target.path", "missing");
        doc.warn(cf + ".target.path '" + path + "' is not supported (channel ignored)");
        continue;
      }
      if (gc.target_node < 0) {
        // glTF lets an extension define the target (KHR_animation_pointer).
        doc.warn(cf + ".target: a channel without a node is not supported (ignored)");
        continue;
      }
      const std::string nf = cf + ".target.node";
      if (size_t(gc.target_node) >= model.nodes.size())
        doc.fail(nf, "node " + std::to_string(gc.target_node) + " does not exist");
      if (model.nodes[size_t(gc.target_node)].matrix.size() == 16)
        doc.fail(nf, "nodes[" + std::to_string(gc.target_node) +
                         "] has a matrix; glTF forbids animating such a node (it must use translation, rotation, scale)");
      if (!targets.insert({gc.target_node, path}).second)
        doc.fail(cf + ".target", "nodes[" + std::to_string(gc.target_node) + "]." + path +
                                     " is already the target of another channel of this animation");

      const tinygltf::AnimationSampler& gs = ga.samplers[size_t(gc.sampler)];
      const std::string sf = af + ".samplers[" + std::to_string(gc.sampler) + "]";
      AnimationChannel ch;
      ch.node = gc.target_node;
      ch.path = path == "translation" ? AnimationPath::Translation : path == "rotation" ? AnimationPath::Rotation : AnimationPath::Scale;
      AnimationSampler& s = ch.sampler;
      s.interpolation = gs.interpolation == "STEP"          ? Interpolation::Step
                        : gs.interpolation == "CUBICSPLINE" ? Interpolation::CubicSpline
                                                            : Interpolation::Linear;
      s.rotation = ch.path == AnimationPath::Rotation;
      s.components = s.rotation ? 4 : 3;
      s.times = times[size_t(gc.sampler)];
      const std::string of = sf + ".output";
      // readFloats checks the accessor, its type (VEC3 / VEC4) and that
      // every value is finite; rotations may be normalized integers
      // (KHR_mesh_quantization), which it converts.
      const std::vector<float> v = doc.readFloats(gs.output, of + " (" + cf + " targets " + path + ")", s.components);
      const size_t perKey = s.interpolation == Interpolation::CubicSpline ? 3 : 1;
      const size_t keys = s.times.size(), count = v.size() / size_t(s.components);
      if (count != perKey * keys)
        doc.fail(of, "count " + std::to_string(count) + " does not match the input's " + std::to_string(keys) +
                         " keyframes (expected " + (perKey == 3 ? "3 x " + std::to_string(keys) + " = " : "") +
                         std::to_string(perKey * keys) + (perKey == 3 ? ": in-tangent, value, out-tangent per key" : "") + ")");
      s.values.assign(v.begin(), v.end());
      if (s.rotation) {
        // A keyed rotation must be a rotation (the tangents of a
        // CUBICSPLINE sampler are not quaternions and may be anything).
        for (size_t k = 0; k < keys; ++k) {
          const double* q = s.values.data() + (perKey * k + (perKey == 3 ? 1 : 0)) * 4;
          const double len = std::sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]);
          if (!(len > 0)) doc.fail(of, "keyframe " + std::to_string(k) + " is not a valid quaternion (length 0)");
          // LINEAR's slerp needs unit keys; the spec requires them, exporters round.
          if (perKey == 1)
            for (size_t c = 0; c < 4; ++c) s.values[4 * k + c] /= len;
        }
      }
      anim.start = anyKey ? std::min(anim.start, s.times.front()) : s.times.front();
      anim.end = anyKey ? std::max(anim.end, s.times.back()) : s.times.back();
      anyKey = true;
      anim.nodes.push_back(ch.node);
      anim.channels.push_back(std::move(ch));
    }
    std::sort(anim.nodes.begin(), anim.nodes.end());
    anim.nodes.erase(std::unique(anim.nodes.begin(), anim.nodes.end()), anim.nodes.end());
    out.push_back(std::move(anim));
  }
  return out;
}

std::string animationLabel(const std::vector<Animation>& animations, size_t i) {
  return animations[i].name.empty() ? "animations[" + std::to_string(i) + "]" : animations[i].name;
}

std::vector<size_t> selectAnimations(const GltfDocument& doc, const std::vector<Animation>& animations,
                                     const std::vector<std::string>& selection) {
  std::vector<size_t> out;
  if (selection.empty()) {
    for (size_t i = 0; i < animations.size(); ++i) out.push_back(i);
    return out;
  }
  for (const std::string& want : selection) {
    size_t found = animations.size();
    for (size_t i = 0; i < animations.size() && found == animations.size(); ++i)
      if (!animations[i].name.empty() && animations[i].name == want) found = i;
    if (found == animations.size() && !want.empty() && want.size() < 10 &&
        want.find_first_not_of("0123456789") == std::string::npos && std::stoul(want) < animations.size())
      found = std::stoul(want);
    if (found == animations.size()) {
      std::string list;
      for (size_t i = 0; i < animations.size(); ++i)
        list += (list.empty() ? "" : ", ") + std::to_string(i) + " '" + animationLabel(animations, i) + "'";
      doc.fail(settingName(Setting::Animations) + " '" + want + "'",
               "no animation has this name or index (" + (animations.empty() ? std::string("the file has no animations")
                                                                              : "animations: " + list) + ")");
    }
    out.push_back(found);
  }
  std::sort(out.begin(), out.end());
  out.erase(std::unique(out.begin(), out.end()), out.end());
  return out;
}

}  // namespace obscura
