// Objects and their roles: who is seen by the camera, who occludes whom
// (docs/production.md "Objects and roles").
//
// An object is a glTF node with a mesh (each placement its own object) or an
// OBJ cage. Its roles come from `extras.obscura` on the node (inherited by
// the node's children unless they set their own) and from `--object`
// overrides matched against object names with shell globs.
//
// How they are traced (docs/architecture.md "Roles as masks, scopes as an opt-in filter, alpha on the geometries that have it"):
// - `camera` and `occluder` are Embree geometry masks on the object's
//   top-level geometry: camera rays carry kRayMaskCamera, every other ray
//   kRayMaskSecondary, and Embree skips a geometry whose mask shares no bit
//   with the ray's. Masks are tested whether or not they are set, so a scene
//   without roles traces exactly as before, at the same speed.
// - `matte` objects are seen by the camera and then treated as a miss by the
//   render loop (a holdout: alpha 0 and pass 0 where they cover).
// - `occlusion` = self / others needs the object a secondary ray leaves
//   from (the ray's id, RayBatch::push) and an Embree context filter that
//   compares it with the object hit; only scenes with such an object turn
//   the filter on.
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include <obscura/ray_batch.h>

namespace obscura {

// Ray masks (kRayMaskCamera, kRayMaskSecondary: RTCRay::mask against
// rtcSetGeometryMask) and kNoObject: obscura/ray_batch.h.

// Which occluders count for rays leaving an object.
enum class OcclusionScope : uint8_t {
  All,     // every occluder (the default)
  Self,    // only the object itself (Arnold self_only, Cycles "Only Local")
  Others,  // every occluder but the object itself (V-Ray "ignore self occlusion")
};

struct ObjectRoles {
  bool occluder = true;  // false: invisible to every secondary ray of every integrator
  bool camera = true;    // false: not seen by the camera, still occluding
  bool matte = false;    // a holdout: seen by the camera as A = 0, pass 0; still occluding
  OcclusionScope occlusion = OcclusionScope::All;

  bool isDefault() const { return occluder && camera && !matte && occlusion == OcclusionScope::All; }
  // "occluder=true,camera=true,matte=false,occlusion=all".
  std::string describe() const;
  // The Embree geometry mask these roles give the object's geometry.
  uint32_t mask() const { return (camera ? kRayMaskCamera : 0u) | (occluder ? kRayMaskSecondary : 0u); }
};

const char* scopeName(OcclusionScope s);

// Some roles, as an override or a node's extras set them (unset = inherited).
struct RoleSettings {
  std::optional<bool> occluder, camera, matte;
  std::optional<OcclusionScope> occlusion;
  void applyTo(ObjectRoles& r) const;
  // Sets `key` from its text value; throws obscura::Error "`where`: ..."
  // naming the key and the accepted values.
  void set(const std::string& key, const std::string& value, const std::string& where);
  // The roles' names, for messages and `--help`.
  static const char* keys() { return "occluder, camera, matte, occlusion"; }
};

// One `--object GLOB:key=value[,key=value...]` option.
struct ObjectOverride {
  std::string text;  // as given, for messages and the EXR header
  std::string glob;  // shell glob (fnmatch) over object names
  RoleSettings roles;
};
// Parses an override; throws obscura::Error naming `--object` and the text.
ObjectOverride parseObjectOverride(const std::string& text);
// Does `name` match the override's glob?
bool matches(const ObjectOverride& o, const std::string& name);

struct SceneObject {
  std::string name;  // the glTF node's name (else its mesh's, else "nodes[i]"), or the OBJ file's name
  ObjectRoles roles;
};

// The objects whose roles are not the default, as "name: roles" joined by
// "; " ("" when every object has the default roles): the EXR header's record.
std::string nonDefaultRoles(const std::vector<SceneObject>& objects);

// Applies the overrides, in order, to the objects whose name matches; an
// override that matches no object throws obscura::Error naming it and
// listing (some of) the objects there are.
void applyObjectOverrides(std::vector<SceneObject>& objects, const std::vector<ObjectOverride>& overrides);

}  // namespace obscura
