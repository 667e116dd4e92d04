#include "core/scene/objects.h"

#include <fnmatch.h>

#include <obscura/error.h>

namespace obscura {

const char* scopeName(OcclusionScope s) {
  switch (s) {
    case OcclusionScope::Self: return "self";
    case OcclusionScope::Others: return "others";
    case OcclusionScope::All: break;
  }
  return "all";
}

std::string ObjectRoles::describe() const {
  const auto b = [](bool v) { return v ? "true" : "false"; };
  return std::string("occluder=") + b(occluder) + ",camera=" + b(camera) + ",matte=" + b(matte) +
         ",occlusion=" + scopeName(occlusion);
}

void RoleSettings::applyTo(ObjectRoles& r) const {
  if (occluder) r.occluder = *occluder;
  if (camera) r.camera = *camera;
  if (matte) r.matte = *matte;
  if (occlusion) r.occlusion = *occlusion;
}

void RoleSettings::set(const std::string& key, const std::string& value, const std::string& where) {
  const auto boolean = [&](std::optional<bool>& out) {
    if (value == "true" || value == "1" || value == "on") out = true;
    else if (value == "false" || value == "0" || value == "off") out = false;
    else throw Error(where + ": " + key + ": expected true or false, got '" + value + "'");
  };
  if (key == "occluder") boolean(occluder);
  else if (key == "camera") boolean(camera);
  else if (key == "matte") boolean(matte);
  else if (key == "occlusion") {
    if (value == "all") occlusion = OcclusionScope::All;
    else if (value == "self") occlusion = OcclusionScope::Self;
    else if (value == "others") occlusion = OcclusionScope::Others;
    else throw Error(where + ": occlusion: expected all, self or others, got '" + value + "'");
  } else {
    throw Error(where + ": unknown role '" + key + "' (roles: " + keys() + ")");
  }
}

ObjectOverride parseObjectOverride(const std::string& text) {
  const std::string where = "--object '" + text + "'";
  // The glob may itself contain ':' only inside brackets; the roles follow
  // the last ':' (role values never contain one).
  const size_t colon = text.rfind(':');
  if (colon == std::string::npos || colon == 0 || colon + 1 == text.size())
    throw Error(where + ": expected GLOB:role=value[,role=value...] (roles: " + RoleSettings::keys() + ")");
  ObjectOverride o;
  o.text = text;
  o.glob = text.substr(0, colon);
  size_t begin = colon + 1;
  while (begin <= text.size()) {
    size_t end = text.find(',', begin);
    if (end == std::string::npos) end = text.size();
    const std::string item = text.substr(begin, end - begin);
    const size_t eq = item.find('=');
    if (eq == std::string::npos || eq == 0) throw Error(where + ": expected role=value, got '" + item + "'");
    o.roles.set(item.substr(0, eq), item.substr(eq + 1), where);
    begin = end + 1;
  }
  return o;
}

bool matches(const ObjectOverride& o, const std::string& name) { return fnmatch(o.glob.c_str(), name.c_str(), 0) == 0; }

std::string nonDefaultRoles(const std::vector<SceneObject>& objects) {
  std::string out;
  for (const SceneObject& o : objects)
    if (!o.roles.isDefault()) out += (out.empty() ? "" : "; ") + o.name + ": " + o.roles.describe();
  return out;
}

void applyObjectOverrides(std::vector<SceneObject>& objects, const std::vector<ObjectOverride>& overrides) {
  for (const ObjectOverride& o : overrides) {
    bool any = false;
    for (SceneObject& obj : objects)
      if (matches(o, obj.name)) o.roles.applyTo(obj.roles), any = true;
    if (any) continue;
    std::string names;
    size_t listed = 0;
    for (const SceneObject& obj : objects) {
      if (listed == 8) {
        names += ", ... (" + std::to_string(objects.size()) + " in all; `obscura info` lists them)";
        break;
      }
      names += (listed++ ? ", " : "") + ("'" + obj.name + "'");
    }
    throw Error("--object '" + o.text + "': no object is named '" + o.glob + "' (objects: " +
                (names.empty() ? "none" : names) + ")");
  }
}

}  // namespace obscura
