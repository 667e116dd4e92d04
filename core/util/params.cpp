#include <obscura/params.h>

#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <limits>

#include <obscura/error.h>

namespace obscura {

std::string formatFloat(double v) {
  if (std::isinf(v)) return v > 0 ? "inf" : "-inf";
  char buf[64];
  for (int prec = 6; prec <= 17; ++prec) {
    std::snprintf(buf, sizeof buf, "%.*g", prec, v);
    if (std::strtod(buf, nullptr) == v) break;
  }
  return buf;
}

std::string ParamSpec::typeName() const {
  switch (type) {
    case ParamType::Float: return "float";
    case ParamType::Int: return "int";
    case ParamType::Bool: return "bool";
    case ParamType::Enum: return "enum";
    case ParamType::String: return "string";
  }
  return "?";
}

std::string ParamSpec::rangeText() const {
  if (type == ParamType::Enum) {
    std::string s;
    for (size_t i = 0; i < choices.size(); ++i) s += (i ? "|" : "") + choices[i];
    return s;
  }
  if (type == ParamType::Bool) return "true|false";
  if (type == ParamType::String) return "text";
  const auto fmt = [&](double v) { return type == ParamType::Int ? std::to_string(static_cast<long long>(v)) : formatFloat(v); };
  const std::string hi = allowInfinity ? "inf" : (max >= 1e308 ? "inf" : fmt(max));
  const std::string lo = min <= -1e308 ? "-inf" : fmt(min);
  return "[" + lo + ", " + hi + "]";
}

ParamSet::ParamSet(std::vector<ParamSpec> specs, std::string owner)
    : specs_(std::move(specs)), owner_(std::move(owner)) {
  for (const ParamSpec& s : specs_) values_[s.name] = parse(s, s.defaultValue);
}

const ParamSpec& ParamSet::spec(const std::string& key) const {
  for (const ParamSpec& s : specs_)
    if (s.name == key) return s;
  std::string known;
  for (const ParamSpec& s : specs_) known += (known.empty() ? "" : ", ") + s.name;
  throw Error("integrator '" + owner_ + "': unknown parameter '" + key + "'" +
              (known.empty() ? " (it takes none)" : " (known: " + known + ")"));
}

ParamSet::Value ParamSet::parse(const ParamSpec& s, const std::string& text) const {
  const std::string where = "integrator '" + owner_ + "': parameter '" + s.name + "'";
  const auto bad = [&](const std::string& why) {
    return Error(where + ": " + why + " (got '" + text + "', expected " + s.typeName() + " " + s.rangeText() + ")");
  };
  switch (s.type) {
    case ParamType::Float: {
      double v;
      if (text == "inf" || text == "+inf" || text == "infinity") {
        if (!s.allowInfinity) throw bad("infinity is not allowed");
        return std::numeric_limits<double>::infinity();
      }
      errno = 0;
      char* end = nullptr;
      v = std::strtod(text.c_str(), &end);
      if (text.empty() || *end != '\0' || (errno == ERANGE && std::isinf(v))) throw bad("not a number");
      if (!std::isfinite(v)) throw bad("not a finite number");
      if (v < s.min || v > s.max) throw bad("out of range");
      return v;
    }
    case ParamType::Int: {
      errno = 0;
      char* end = nullptr;
      const long long v = std::strtoll(text.c_str(), &end, 10);
      if (text.empty() || *end != '\0' || errno == ERANGE) throw bad("not an integer");
      // An int holds the value: a spec without a range (a plugin's) must
      // not let 4294967297 wrap around to 1.
      if (v < std::numeric_limits<int>::min() || v > std::numeric_limits<int>::max() || double(v) < s.min ||
          double(v) > s.max)
        throw bad("out of range");
      return int(v);
    }
    case ParamType::Bool:
      if (text == "true" || text == "1" || text == "on" || text == "yes") return true;
      if (text == "false" || text == "0" || text == "off" || text == "no") return false;
      throw bad("not a boolean");
    case ParamType::Enum:
      for (const auto& c : s.choices)
        if (c == text) return text;
      throw bad("not one of the choices");
    case ParamType::String: return text;
  }
  throw bad("unknown type");
}

void ParamSet::set(const std::string& key, const std::string& value) {
  const ParamSpec& s = spec(key);
  values_[key] = parse(s, value);
}

void ParamSet::setAssignment(const std::string& assignment) {
  const size_t eq = assignment.find('=');
  if (eq == std::string::npos || eq == 0)
    throw Error("integrator '" + owner_ + "': parameter '" + assignment + "' is not of the form key=value");
  set(assignment.substr(0, eq), assignment.substr(eq + 1));
}

double ParamSet::getFloat(const std::string& key) const { return std::get<double>(values_.at(spec(key).name)); }
int ParamSet::getInt(const std::string& key) const { return std::get<int>(values_.at(spec(key).name)); }
bool ParamSet::getBool(const std::string& key) const { return std::get<bool>(values_.at(spec(key).name)); }
const std::string& ParamSet::getEnum(const std::string& key) const {
  return std::get<std::string>(values_.at(spec(key).name));
}
const std::string& ParamSet::getString(const std::string& key) const {
  return std::get<std::string>(values_.at(spec(key).name));
}

std::vector<std::pair<std::string, std::string>> ParamSet::values() const {
  std::vector<std::pair<std::string, std::string>> out;
  for (const ParamSpec& s : specs_) {
    const Value& v = values_.at(s.name);
    std::string text;
    if (auto* d = std::get_if<double>(&v)) text = formatFloat(*d);
    else if (auto* i = std::get_if<int>(&v)) text = std::to_string(*i);
    else if (auto* b = std::get_if<bool>(&v)) text = *b ? "true" : "false";
    else text = std::get<std::string>(v);
    out.emplace_back(s.name, text);
  }
  return out;
}

}  // namespace obscura
