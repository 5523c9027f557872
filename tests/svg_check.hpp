#pragma once
// Checks on SVG text for the tests of the figures: a minimal well-formedness check and substring counting.
#include <string>
#include <vector>

inline size_t countOf(const std::string& text, const std::string& what) {
  size_t n = 0;
  for (size_t pos = text.find(what); pos != std::string::npos; pos = text.find(what, pos + what.size())) ++n;
  return n;
}

// Minimal XML check: every start tag is closed by its end tag in order, and every '&' starts an entity.
inline bool wellFormed(const std::string& xml, std::string& problem) {
  std::vector<std::string> open;
  size_t pos = 0;
  while ((pos = xml.find('<', pos)) != std::string::npos) {
    const size_t end = xml.find('>', pos);
    if (end == std::string::npos) return problem = "unterminated tag", false;
    const std::string tag = xml.substr(pos + 1, end - pos - 1);
    pos = end + 1;
    if (tag.empty() || tag[0] == '?' || tag[0] == '!') continue;
    if (tag[0] == '/') {
      if (open.empty() || open.back() != tag.substr(1)) return problem = "unexpected </" + tag.substr(1) + ">", false;
      open.pop_back();
    } else if (tag.back() != '/') {
      open.push_back(tag.substr(0, tag.find_first_of(" \t\n")));
    }
  }
  if (!open.empty()) return problem = "<" + open.back() + "> never closed", false;
  for (size_t amp = xml.find('&'); amp != std::string::npos; amp = xml.find('&', amp + 1)) {
    const size_t semi = xml.find(';', amp);
    const std::string entity = semi == std::string::npos ? "" : xml.substr(amp, semi - amp + 1);
    if (entity != "&amp;" && entity != "&lt;" && entity != "&gt;" && entity != "&quot;" && entity != "&apos;")
      return problem = "bare '&'", false;
  }
  return true;
}
