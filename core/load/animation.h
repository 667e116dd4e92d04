// glTF 2.0 animations of node transforms: the samplers (keyframe times and
// values), the channels that aim them at a node's translation, rotation or
// scale, and their evaluation at a time in seconds.
//
// Reading: readAnimations checks `model.animations` field by field and
// decodes the accessors through the document that owns the file
// (GltfDocument, which calls it once while it decodes: the accessor reading
// and the error style are the document's). Input accessors are float
// SCALAR keyframe times, finite and strictly increasing; output counts
// match (x3 for CUBICSPLINE: in-tangent, value, out-tangent per key).
// A channel on a node with a `matrix` is an error (glTF forbids it); a
// `weights` channel (morph targets) is warned about once and ignored.
//
// Evaluation (glTF 2.0 spec, Appendix C "Animation Sampler Interpolation
// Modes"; docs/math.md has no section of its own: these are the spec's
// formulas): before the first key the first value holds, after the last the
// last. LINEAR interpolates linearly, rotations by spherical linear
// interpolation along the shorter arc; STEP holds each key's value until
// the next key; CUBICSPLINE is the cubic Hermite spline with the tangents
// scaled by the key interval, and a rotation it yields is normalised.
// Everything is evaluated in double from the file's float keys.
#pragma once

#include <array>
#include <cstddef>
#include <string>
#include <vector>

namespace obscura {

class GltfDocument;

enum class AnimationPath { Translation, Rotation, Scale };
enum class Interpolation { Linear, Step, CubicSpline };

// One sampler with the values its channel reads: `components` = 3
// (translation, scale) or 4 (rotation, quaternion x, y, z, w).
struct AnimationSampler {
  Interpolation interpolation = Interpolation::Linear;
  int components = 3;
  bool rotation = false;      // slerp (LINEAR) and normalisation (CUBICSPLINE)
  std::vector<double> times;  // seconds, strictly increasing, at least one
  // components per key (LINEAR, STEP) or 3 x components per key (CUBICSPLINE:
  // in-tangent a_k, value v_k, out-tangent b_k), as the file orders them.
  std::vector<double> values;
  // The value at `seconds` into out[0 .. components).
  void evaluate(double seconds, double* out) const;
};

struct AnimationChannel {
  int node = -1;
  AnimationPath path = AnimationPath::Translation;
  AnimationSampler sampler;  // a copy per channel: its components follow the path
};

struct Animation {
  std::string name;          // as the file has it (may be empty)
  std::vector<AnimationChannel> channels;  // the supported ones (weights dropped)
  size_t fileChannels = 0;   // channels[] in the file, every target
  double start = 0, end = 0;  // the earliest and latest key of its channels (0, 0 if none)
  std::vector<int> nodes;    // the nodes its channels target, ascending
};

// animations[] of the document's file, checked (see above). Called by
// GltfDocument while it decodes; errors go through document.fail.
std::vector<Animation> readAnimations(const GltfDocument& document);

// "name" of animations[i] as messages and listings show it: its name, else "animations[i]".
std::string animationLabel(const std::vector<Animation>& animations, size_t i);

// The animations a selection plays, by index, ascending and without
// repeats: each entry a name, else an index (decimal); empty = all of them.
// An unknown entry throws obscura::Error "FILE: <what>: ..." listing the
// file's animations (`what` names the setting: core/util/option_names.h).
std::vector<size_t> selectAnimations(const GltfDocument& document, const std::vector<Animation>& animations,
                                     const std::vector<std::string>& selection);

// Spherical linear interpolation of unit quaternions (x, y, z, w) a -> b at
// u in [0, 1] along the shorter arc (b negated when a.b < 0), as the glTF
// spec's Appendix C describes; nearly parallel keys interpolate linearly
// and renormalise (sin(theta) would vanish).
std::array<double, 4> slerp(const std::array<double, 4>& a, const std::array<double, 4>& b, double u);

}  // namespace obscura
