#include <obscura/lobe.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>

#include <obscura/error.h>

namespace obscura {

void addLobeParams(std::vector<ParamSpec>& out, LobeSet set) {
  const std::vector<ParamSpec> specs = {
      {.name = "inside", .type = ParamType::Bool, .defaultValue = "false", .choices = {},
       .doc = "invert the normal: sample the hemisphere behind the surface (interior occlusion, thickness; "
              "docs/math.md §11)"},
      {.name = "spread", .type = ParamType::Float, .defaultValue = "1", .min = 0.0, .max = 1.0, .choices = {},
       .doc = "the lobe's half-angle as a fraction of 90 degrees, in (0, 1]: directions cosine-distributed in "
              "that cone, normalised so an open surface gives 1 (docs/math.md §11)"},
      {.name = "near", .type = ParamType::Float, .defaultValue = "0", .min = 0.0, .max = 1e308, .choices = {},
       .doc = "occluders closer than this along a ray (scene units) are ignored; when positive it must be "
              "below `distance` (docs/math.md §11)"},
  };
  for (const ParamSpec& s : specs)
    if (set == LobeSet::All || (set == LobeSet::SpreadNear && s.name != "inside") || s.name == "near") out.push_back(s);
}

namespace {
bool declares(const ParamSet& p, const char* name) {
  for (const ParamSpec& s : p.specs())
    if (s.name == name) return true;
  return false;
}
}  // namespace

LobeControls lobeFromParams(const ParamSet& p, double distance) {
  LobeControls c;
  const std::string where = "integrator '" + p.owner() + "': parameter ";
  if (declares(p, "inside") && p.getBool("inside")) c.sign = -1.0f;
  if (declares(p, "spread")) {
    const double spread = p.getFloat("spread");
    if (!(spread > 0.0))
      throw Error(where + "'spread': must be greater than 0 (got '" + formatFloat(spread) +
                  "', expected float (0, 1]: the half-angle of the lobe as a fraction of 90 degrees)");
    // spread = 1 keeps the exact 1 and 0 of the hemisphere (sin and cos of
    // the double nearest pi/2 are not exactly those).
    if (spread < 1.0) {
      const double theta = spread * (std::numbers::pi / 2.0);
      c.sinThetaMax = float(std::sin(theta));
      c.cosThetaMax = float(std::cos(theta));
    }
  }
  if (declares(p, "near")) {
    const double near = p.getFloat("near");
    if (near > 0.0 && !(near < distance))
      throw Error(where + "'near' (" + formatFloat(near) + ") must be less than parameter 'distance' (" +
                  formatFloat(distance) + "): every occluder would be ignored");
    // Beyond float range a ray finds nothing anyway; an inf tnear is not
    // something to hand Embree.
    c.tnear = float(std::min(near, double(std::numeric_limits<float>::max())));
  }
  return c;
}

}  // namespace obscura
