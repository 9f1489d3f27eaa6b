#include "aosr/io/config.hpp"

#include <cmath>
#include <filesystem>
#include <fstream>
#include <sstream>

#include "aosr/core/error.hpp"

namespace aosr {

ConfigNode::ConfigNode(const nlohmann::json& node, std::string source, std::string path)
    : node_(node), source_(std::move(source)), path_(std::move(path)) {
  if (!node_.is_object()) Fail("", node_.type_name(), "a JSON object");
}

std::string ConfigNode::FieldPath(const std::string& key) const {
  if (key.empty()) return path_.empty() ? "(top level)" : path_;
  return path_.empty() ? key : path_ + "." + key;
}

void ConfigNode::Fail(const std::string& key, const std::string& value, const std::string& allowed) const {
  throw InvalidArgument(source_ + ": " + FieldPath(key) + " = " + value + "; allowed: " + allowed);
}

bool ConfigNode::Has(const std::string& key) const { return node_.contains(key) && !node_.at(key).is_null(); }

const nlohmann::json& ConfigNode::Field(const std::string& key) const {
  read_.insert(key);
  if (!node_.contains(key)) Fail(key, "(missing)", "a value (required field)");
  return node_.at(key);
}

ConfigNode ConfigNode::Child(const std::string& key) const {
  const nlohmann::json& f = Field(key);
  if (!f.is_object()) Fail(key, f.dump(), "a JSON object");
  return ConfigNode(f, source_, FieldPath(key));
}

std::vector<ConfigNode> ConfigNode::Array(const std::string& key) const {
  const nlohmann::json& f = Field(key);
  if (!f.is_array()) Fail(key, f.dump(), "a JSON array");
  std::vector<ConfigNode> out;
  for (std::size_t i = 0; i < f.size(); ++i) {
    if (!f[i].is_object()) Fail(key + "[" + std::to_string(i) + "]", f[i].dump(), "a JSON object");
    out.emplace_back(f[i], source_, FieldPath(key) + "[" + std::to_string(i) + "]");
  }
  return out;
}

double ConfigNode::Number(const std::string& key, double lo, double hi) const {
  const nlohmann::json& f = Field(key);
  if (!f.is_number()) Fail(key, f.dump(), "a number in [" + ToString(lo) + ", " + ToString(hi) + "]");
  const double v = f.get<double>();
  if (!(std::isfinite(v) && v >= lo && v <= hi)) Fail(key, f.dump(), "a number in [" + ToString(lo) + ", " + ToString(hi) + "]");
  return v;
}

std::vector<double> ConfigNode::Numbers(const std::string& key, double lo, double hi, std::size_t min_size,
                                        std::size_t max_size) const {
  const nlohmann::json& f = Field(key);
  const std::string size = min_size == max_size ? std::to_string(min_size)
                                                : std::to_string(min_size) + " to " + std::to_string(max_size);
  const std::string allowed = "an array of " + size + " numbers, each in [" + ToString(lo) + ", " + ToString(hi) + "]";
  if (!f.is_array() || f.size() < min_size || f.size() > max_size) Fail(key, f.dump(), allowed);
  std::vector<double> out;
  for (std::size_t i = 0; i < f.size(); ++i) {
    const std::string item = key + "[" + std::to_string(i) + "]";
    if (!f[i].is_number()) Fail(item, f[i].dump(), "a number in [" + ToString(lo) + ", " + ToString(hi) + "]");
    const double v = f[i].get<double>();
    if (!(std::isfinite(v) && v >= lo && v <= hi))
      Fail(item, f[i].dump(), "a number in [" + ToString(lo) + ", " + ToString(hi) + "]");
    out.push_back(v);
  }
  return out;
}

double ConfigNode::NumberOr(const std::string& key, double fallback, double lo, double hi) const {
  read_.insert(key);
  return Has(key) ? Number(key, lo, hi) : fallback;
}

double ConfigNode::Positive(const std::string& key) const {
  const nlohmann::json& f = Field(key);
  if (!f.is_number() || !(std::isfinite(f.get<double>()) && f.get<double>() > 0))
    Fail(key, f.dump(), "a finite number > 0");
  return f.get<double>();
}

double ConfigNode::PositiveOr(const std::string& key, double fallback) const {
  read_.insert(key);
  return Has(key) ? Positive(key) : fallback;
}

long long ConfigNode::Integer(const std::string& key, long long lo, long long hi) const {
  const nlohmann::json& f = Field(key);
  const std::string allowed = "an integer in [" + std::to_string(lo) + ", " + std::to_string(hi) + "]";
  if (!f.is_number_integer()) Fail(key, f.dump(), allowed);
  const long long v = f.get<long long>();
  if (v < lo || v > hi) Fail(key, f.dump(), allowed);
  return v;
}

long long ConfigNode::IntegerOr(const std::string& key, long long fallback, long long lo, long long hi) const {
  read_.insert(key);
  return Has(key) ? Integer(key, lo, hi) : fallback;
}

bool ConfigNode::BoolOr(const std::string& key, bool fallback) const {
  read_.insert(key);
  if (!Has(key)) return fallback;
  const nlohmann::json& f = Field(key);
  if (!f.is_boolean()) Fail(key, f.dump(), "true or false");
  return f.get<bool>();
}

std::string ConfigNode::String(const std::string& key) const {
  const nlohmann::json& f = Field(key);
  if (!f.is_string()) Fail(key, f.dump(), "a string");
  return f.get<std::string>();
}

std::string ConfigNode::StringOr(const std::string& key, const std::string& fallback) const {
  read_.insert(key);
  return Has(key) ? String(key) : fallback;
}

std::string ConfigNode::Choice(const std::string& key, const std::vector<std::string>& allowed) const {
  const std::string v = String(key);
  for (const auto& a : allowed)
    if (v == a) return v;
  std::string list;
  for (const auto& a : allowed) list += (list.empty() ? "" : ", ") + a;
  Fail(key, "\"" + v + "\"", "one of " + list);
}

std::string ConfigNode::ChoiceOr(const std::string& key, const std::string& fallback,
                                 const std::vector<std::string>& allowed) const {
  read_.insert(key);
  return Has(key) ? Choice(key, allowed) : fallback;
}

void ConfigNode::CheckNoOtherFields() const {
  for (auto it = node_.begin(); it != node_.end(); ++it)
    if (!read_.count(it.key()) && it.key().rfind("comment", 0) != 0)
      Fail(it.key(), "(unknown field)", "only the documented fields (keys starting with \"comment\" are ignored)");
}

nlohmann::json ReadJsonFile(const std::string& path) {
  // Only regular files: a device or FIFO (/dev/zero) never ends, and reading it would fill the memory.
  std::error_code ec;
  const auto type = std::filesystem::status(path, ec).type();
  if (type == std::filesystem::file_type::character || type == std::filesystem::file_type::block ||
      type == std::filesystem::file_type::fifo || type == std::filesystem::file_type::socket)
    throw IoError(path, "is not a regular file (a device, FIFO or socket)");
  std::ifstream in(path);
  if (!in) throw IoError(path, "cannot open for reading");
  std::stringstream buf;
  buf << in.rdbuf();
  try {
    return nlohmann::json::parse(buf.str());
  } catch (const nlohmann::json::exception& e) {
    // parse_error, and out_of_range 406 for a number beyond double's range ("1e999"): the parser throws both.
    throw InvalidArgument(path + ": malformed JSON: " + e.what());
  }
}

}  // namespace aosr
