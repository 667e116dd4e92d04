// Typed integrator parameters: declared with type, default, range and one
// line of documentation; set from "key=value" strings; validated on set.
//
// Reading a key that was not declared, or setting one, is an error that
// names it (as pbrt-v4 does): a typo never silently falls back to a default.
#pragma once

#include <map>
#include <string>
#include <variant>
#include <vector>

namespace obscura {

// String: free text (a file path, ...); appended last so the values of the
// other types, which plugins compile in, do not change.
enum class ParamType { Float, Int, Bool, Enum, String };

struct ParamSpec {
  std::string name;
  ParamType type = ParamType::Float;
  std::string defaultValue;        // as the user would type it
  double min = -1e308, max = 1e308;  // inclusive range for Float and Int
  bool allowInfinity = false;      // Float: accept "inf" (= +infinity)
  std::vector<std::string> choices;  // Enum
  std::string doc;

  std::string typeName() const;
  std::string rangeText() const;  // e.g. "[0, inf]" or "step|linear"
};

class ParamSet {
 public:
  ParamSet() = default;
  // The integrator's declarations; every value starts at its default.
  explicit ParamSet(std::vector<ParamSpec> specs, std::string owner);

  // Parses and validates `value` for `key`; throws obscura::Error naming the
  // owner, key and value on failure.
  void set(const std::string& key, const std::string& value);
  // Parses "key=value".
  void setAssignment(const std::string& assignment);

  double getFloat(const std::string& key) const;
  int getInt(const std::string& key) const;
  bool getBool(const std::string& key) const;
  const std::string& getEnum(const std::string& key) const;
  const std::string& getString(const std::string& key) const;

  // Every parameter's current value, as text, in declaration order.
  std::vector<std::pair<std::string, std::string>> values() const;
  const std::vector<ParamSpec>& specs() const { return specs_; }
  // The integrator's name, as messages give it.
  const std::string& owner() const { return owner_; }

 private:
  using Value = std::variant<double, int, bool, std::string>;
  Value parse(const ParamSpec& spec, const std::string& text) const;
  const ParamSpec& spec(const std::string& key) const;
  std::vector<ParamSpec> specs_;
  std::map<std::string, Value> values_;
  std::string owner_;
};

// Float formatting that round-trips (shortest "%.9g"), with inf spelled "inf".
std::string formatFloat(double v);

}  // namespace obscura
