// Strict reading of JSON configuration files (telescope presets, scenes, designs).
//
// Rules, written once for every config in aosr:
//  * Every error is an InvalidArgument whose message starts with the file and the full field path,
//    e.g. "data/scenes/x.json: atmosphere.layers[1].cn2_fraction = -0.2; allowed: in [0, 1]".
//  * Unknown fields are errors (a typo must not silently fall back to a default): call
//    CheckNoOtherFields() after reading an object's fields.
//  * Numbers are checked for type and range at read time; units are in the field name (…_m, …_deg)
//    and converted to SI by the caller.
#pragma once

#include <nlohmann/json.hpp>
#include <set>
#include <string>
#include <vector>

namespace aosr {

class ConfigNode {
 public:
  // `source` names the file (or "<string>") for messages; `path` is the field path of `node`.
  ConfigNode(const nlohmann::json& node, std::string source, std::string path = "");

  bool Has(const std::string& key) const;
  // A required / optional child object or array element.
  ConfigNode Child(const std::string& key) const;
  std::vector<ConfigNode> Array(const std::string& key) const;  // required array

  // Typed fields. Range checks: [lo, hi] inclusive; use the *Optional forms for defaults.
  double Number(const std::string& key, double lo, double hi) const;
  double NumberOr(const std::string& key, double fallback, double lo, double hi) const;
  // Strictly positive finite number.
  double Positive(const std::string& key) const;
  double PositiveOr(const std::string& key, double fallback) const;
  long long Integer(const std::string& key, long long lo, long long hi) const;
  long long IntegerOr(const std::string& key, long long fallback, long long lo, long long hi) const;
  bool BoolOr(const std::string& key, bool fallback) const;
  // A required array of numbers, each in [lo, hi], with between min_size and max_size elements.
  std::vector<double> Numbers(const std::string& key, double lo, double hi, std::size_t min_size,
                              std::size_t max_size) const;
  std::string String(const std::string& key) const;
  std::string StringOr(const std::string& key, const std::string& fallback) const;
  // A string that must be one of `allowed`.
  std::string Choice(const std::string& key, const std::vector<std::string>& allowed) const;
  std::string ChoiceOr(const std::string& key, const std::string& fallback, const std::vector<std::string>& allowed) const;

  // Throws naming the first field of this object that no accessor above has read.
  void CheckNoOtherFields() const;

  // Throws InvalidArgument "<source>: <path>.<key> ...; allowed: ..." (for checks made by the caller).
  [[noreturn]] void Fail(const std::string& key, const std::string& value, const std::string& allowed) const;

  const std::string& path() const { return path_; }
  const std::string& source() const { return source_; }
  const nlohmann::json& json() const { return node_; }

 private:
  const nlohmann::json& Field(const std::string& key) const;
  std::string FieldPath(const std::string& key) const;

  const nlohmann::json& node_;
  std::string source_;
  std::string path_;
  mutable std::set<std::string> read_;
};

// Parses a JSON file (IoError naming the path if missing/unreadable, InvalidArgument with line and column if
// malformed).
nlohmann::json ReadJsonFile(const std::string& path);

}  // namespace aosr
