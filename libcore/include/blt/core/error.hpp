#pragma once
// Errors for bad input. Every message names where the input came from (a CLI flag or a file and line),
// the field, the offending value and what is allowed, so a user can fix it without reading code.

#include <optional>
#include <stdexcept>
#include <string>

namespace blt {

// Where a value came from: a CLI flag ("--velocity"), or a file with an optional line and field.
struct InputLocation {
  std::string source;           // flag name or file path
  std::optional<int> line;      // 1-based line in the file, when known
  std::string field;            // column, key or parameter name, when known

  static InputLocation flag(std::string name) { return {std::move(name), std::nullopt, {}}; }
  static InputLocation file(std::string path, std::optional<int> line = std::nullopt, std::string field = {}) {
    return {std::move(path), line, std::move(field)};
  }
  InputLocation withField(std::string f) const { InputLocation l = *this; l.field = std::move(f); return l; }
  InputLocation withLine(int n) const { InputLocation l = *this; l.line = n; return l; }

  // "file data.csv, line 4, field 'velocity_km_s'" or "flag --velocity".
  std::string describe() const;
};

// Raised for any input the tool cannot accept. what() is the full, user-facing message.
class InputError : public std::runtime_error {
 public:
  InputError(const InputLocation& where, const std::string& problem, const std::string& allowed = {});
  const InputLocation& where() const { return where_; }
  const std::string& problem() const { return problem_; }

 private:
  InputLocation where_;
  std::string problem_;
};

}  // namespace blt
