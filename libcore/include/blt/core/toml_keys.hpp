#pragma once
// The checked reader of one TOML table, shared by the scenario and campaign files: every key it is asked for is
// marked, finish() rejects the rest, and every error names the file, the line and the dotted key. Nodes that a
// `--set key=value` setting put into the table have no source line; their errors name the --set flag instead.

#include <cmath>
#include <set>
#include <string>
#include <utility>
#include <vector>

#include <toml++/toml.h>

#include "blt/core/error.hpp"
#include "blt/core/units.hpp"

namespace blt {

// Parses TOML text; a syntax error is an InputError naming `sourceName` and the line.
toml::table parseTomlText(const std::string& text, const std::string& sourceName);

class TomlKeys {
 public:
  // `path`: the table's dotted name in the file ("" for the root), `source`: the file (or its stand-in name).
  TomlKeys(const toml::table& table, std::string path, std::string source)
      : table_(table), path_(std::move(path)), source_(std::move(source)) {}

  // Where a key is (or would be: a missing key is placed at its table's line).
  InputLocation at(const std::string& key) const;
  const toml::node* get(const std::string& key);

  std::string string(const std::string& key, const std::string& fallback, bool required = false);
  // A quantity with a unit ("1.2 mm"); dimensionless quantities may be plain numbers.
  double quantity(const std::string& key, const units::Dimension& dim, double fallback, bool required = false);
  double positive(const std::string& key, const units::Dimension& dim, double fallback, bool required = false);
  double nonNegative(const std::string& key, const units::Dimension& dim, double fallback);
  // A non-empty list of quantities (["2 km/s", "3 km/s"]); each entry's errors name its own line. Empty when absent.
  std::vector<double> quantities(const std::string& key, const units::Dimension& dim);
  bool boolean(const std::string& key, bool fallback);
  int integer(const std::string& key, int fallback, int lowest);
  template <class E>
  E choice(const std::string& key, const std::vector<std::pair<std::string, E>>& options, E fallback) {
    const toml::node* n = get(key);
    if (!n) return fallback;
    std::string allowed;
    for (const auto& o : options) allowed += (allowed.empty() ? "" : ", ") + o.first;
    auto s = n->as_string();
    if (!s) throw InputError(at(key), "must be a string", allowed);
    for (const auto& o : options)
      if (o.first == s->get()) return o.second;
    throw InputError(at(key), "unknown value '" + s->get() + "'", allowed);
  }
  // A sub-table, or nullptr when absent.
  const toml::table* table(const std::string& key);
  // Throws for the first key that was never asked for, naming the ones that were.
  void finish() const;

  std::string child(const std::string& key) const { return path_.empty() ? key : path_ + "." + key; }
  const std::string& source() const { return source_; }

 private:
  double quantityOf(const toml::node& n, const units::Dimension& dim, const InputLocation& where) const;

  const toml::table& table_;
  std::string path_, source_;
  std::set<std::string> seen_;
};

}  // namespace blt
