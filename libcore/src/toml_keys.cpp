#include "blt/core/toml_keys.hpp"

namespace blt {

toml::table parseTomlText(const std::string& text, const std::string& sourceName) {
  try {
    return toml::parse(text, sourceName);
  } catch (const toml::parse_error& e) {
    throw InputError(InputLocation::file(sourceName, static_cast<int>(e.source().begin.line)),
                     "not valid TOML: " + std::string(e.description()));
  }
}

InputLocation TomlKeys::at(const std::string& key) const {
  const toml::node* n = table_.get(key);
  if (n && n->source().begin.line == 0) return InputLocation{"--set", std::nullopt, child(key)};
  InputLocation l = InputLocation::file(source_, std::nullopt, child(key));
  const auto line = n ? n->source().begin.line : table_.source().begin.line;
  if (line > 0) l.line = static_cast<int>(line);
  return l;
}

const toml::node* TomlKeys::get(const std::string& key) {
  seen_.insert(key);
  return table_.get(key);
}

std::string TomlKeys::string(const std::string& key, const std::string& fallback, bool required) {
  const toml::node* n = get(key);
  if (!n) {
    if (required) throw InputError(at(key), "the required key is missing");
    return fallback;
  }
  if (auto s = n->as_string()) return s->get();
  throw InputError(at(key), "must be a string");
}

double TomlKeys::quantityOf(const toml::node& n, const units::Dimension& dim, const InputLocation& where) const {
  if (auto s = n.as_string()) return units::parse(s->get(), dim, where);
  if (auto v = n.value<double>()) {
    if (dim == units::dimensionless) return *v;
    throw InputError(where, "the number has no unit; a unit is required",
                     "a " + units::describe(dim) + " such as \"" + units::example(dim) + "\"");
  }
  throw InputError(where, "not a quantity", "a string with a unit such as \"" + units::example(dim) + "\"");
}

double TomlKeys::quantity(const std::string& key, const units::Dimension& dim, double fallback, bool required) {
  const toml::node* n = get(key);
  if (!n) {
    if (required) throw InputError(at(key), "the required key is missing", "e.g. \"" + units::example(dim) + "\"");
    return fallback;
  }
  return quantityOf(*n, dim, at(key));
}

double TomlKeys::positive(const std::string& key, const units::Dimension& dim, double fallback, bool required) {
  const double v = quantity(key, dim, fallback, required);
  if (table_.get(key) && !(v > 0)) throw InputError(at(key), "must be positive");
  return v;
}

double TomlKeys::nonNegative(const std::string& key, const units::Dimension& dim, double fallback) {
  const double v = quantity(key, dim, fallback);
  if (!(v >= 0)) throw InputError(at(key), "must not be negative");
  return v;
}

std::vector<double> TomlKeys::quantities(const std::string& key, const units::Dimension& dim) {
  const toml::node* n = get(key);
  std::vector<double> values;
  if (!n) return values;
  const toml::array* a = n->as_array();
  if (!a || a->empty())
    throw InputError(at(key), "must be a non-empty list", "e.g. [\"" + units::example(dim) + "\", ...]");
  for (const toml::node& e : *a) {
    InputLocation where = at(key);
    if (e.source().begin.line > 0) where.line = static_cast<int>(e.source().begin.line);
    values.push_back(quantityOf(e, dim, where));
  }
  return values;
}

bool TomlKeys::boolean(const std::string& key, bool fallback) {
  const toml::node* n = get(key);
  if (!n) return fallback;
  if (auto b = n->value<bool>()) return *b;
  throw InputError(at(key), "must be true or false");
}

int TomlKeys::integer(const std::string& key, int fallback, int lowest) {
  const toml::node* n = get(key);
  if (!n) return fallback;
  const auto v = n->value_exact<int64_t>();
  if (!v) throw InputError(at(key), "must be a whole number");
  if (*v < lowest) throw InputError(at(key), "too small", "at least " + std::to_string(lowest));
  return static_cast<int>(*v);
}

const toml::table* TomlKeys::table(const std::string& key) {
  const toml::node* n = get(key);
  if (!n) return nullptr;
  if (auto t = n->as_table()) return t;
  throw InputError(at(key), "must be a table", "[" + child(key) + "]");
}

void TomlKeys::finish() const {
  std::string allowed;
  for (const auto& k : seen_) allowed += (allowed.empty() ? "" : ", ") + k;
  for (const auto& [k, node] : table_) {
    const std::string key(k.str());
    if (!seen_.count(key)) throw InputError(at(key), "unknown key", allowed);
  }
}

}  // namespace blt
