#include "blt/core/error.hpp"

namespace blt {

std::string InputLocation::describe() const {
  std::string text;
  if (source.rfind("--", 0) == 0) {
    text = "flag " + source;
  } else if (!source.empty()) {
    text = "file " + source;
  }
  auto append = [&text](const std::string& part) {
    if (!text.empty()) text += ", ";
    text += part;
  };
  if (line) append("line " + std::to_string(*line));
  if (!field.empty()) append("field '" + field + "'");
  return text.empty() ? "input" : text;
}

static std::string composeMessage(const InputLocation& where, const std::string& problem, const std::string& allowed) {
  std::string msg = where.describe() + ": " + problem;
  if (!allowed.empty()) msg += " (allowed: " + allowed + ")";
  return msg;
}

InputError::InputError(const InputLocation& where, const std::string& problem, const std::string& allowed)
    : std::runtime_error(composeMessage(where, problem, allowed)), where_(where), problem_(problem) {}

}  // namespace blt
