#include "blt/core/csv.hpp"

#include <algorithm>
#include <cctype>
#include <charconv>
#include <cmath>
#include <fstream>
#include <sstream>

namespace blt::csv {

namespace {

std::string trim(std::string_view s) {
  size_t b = 0, e = s.size();
  while (b < e && std::isspace(static_cast<unsigned char>(s[b]))) ++b;
  while (e > b && std::isspace(static_cast<unsigned char>(s[e - 1]))) --e;
  return std::string(s.substr(b, e - b));
}

std::vector<std::string> splitFields(std::string_view line) {
  std::vector<std::string> fields;
  std::string current;
  bool quoted = false;
  for (size_t i = 0; i < line.size(); ++i) {
    const char c = line[i];
    if (quoted) {
      if (c == '"' && i + 1 < line.size() && line[i + 1] == '"') {
        current += '"';
        ++i;
      } else if (c == '"') {
        quoted = false;
      } else {
        current += c;
      }
    } else if (c == '"') {
      quoted = true;
    } else if (c == ',') {
      fields.push_back(trim(current));
      current.clear();
    } else {
      current += c;
    }
  }
  fields.push_back(trim(current));
  return fields;
}

bool isSkippable(std::string_view line) {
  const std::string t = trim(line);
  return t.empty() || t[0] == '#';
}

}  // namespace

Table Table::read(const std::string& path, const ReadOptions& options) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw InputError(InputLocation::file(path), "cannot open the file", "an existing, readable CSV file");
  std::stringstream buffer;
  buffer << in.rdbuf();
  return parse(buffer.str(), path, options);
}

Table Table::parse(std::string_view text, const std::string& sourceName, const ReadOptions& options) {
  Table t;
  t.source_ = sourceName;
  if (text.substr(0, 3) == "\xEF\xBB\xBF") text.remove_prefix(3);
  std::vector<std::pair<int, std::string_view>> lines;
  int lineNo = 0;
  size_t pos = 0;
  while (pos <= text.size()) {
    size_t end = text.find('\n', pos);
    if (end == std::string_view::npos) end = text.size();
    std::string_view line = text.substr(pos, end - pos);
    if (!line.empty() && line.back() == '\r') line.remove_suffix(1);
    ++lineNo;
    if (!isSkippable(line)) lines.emplace_back(lineNo, line);
    if (end == text.size()) break;
    pos = end + 1;
  }
  const auto at = InputLocation::file(sourceName);
  if (lines.empty()) throw InputError(at, "the file is empty", "a header line followed by data rows");
  size_t next = 0;
  t.header_ = splitFields(lines[next++].second);
  for (size_t c = 0; c < t.header_.size(); ++c) {
    if (t.header_[c].empty())
      throw InputError(at.withLine(lines[0].first), "column " + std::to_string(c + 1) + " has an empty name");
  }
  if (options.unitRow) {
    if (next >= lines.size()) throw InputError(at, "the unit row is missing", "a header row, then a unit row");
    t.units_ = splitFields(lines[next].second);
    if (t.units_.size() != t.header_.size())
      throw InputError(at.withLine(lines[next].first),
                       "the unit row has " + std::to_string(t.units_.size()) + " fields, the header " +
                           std::to_string(t.header_.size()));
    for (auto& u : t.units_)
      if (u == "-") u.clear();
    ++next;
  } else {
    t.units_.assign(t.header_.size(), std::string());
  }
  for (; next < lines.size(); ++next) {
    auto fields = splitFields(lines[next].second);
    if (fields.size() != t.header_.size())
      throw InputError(at.withLine(lines[next].first),
                       "the row has " + std::to_string(fields.size()) + " fields but the header has " +
                           std::to_string(t.header_.size()));
    t.rows_.push_back(std::move(fields));
    t.lines_.push_back(lines[next].first);
  }
  if (t.rows_.empty()) throw InputError(at, "the file has a header but no data rows", "at least one data row");
  return t;
}

bool Table::hasColumn(std::string_view name) const {
  return std::find(header_.begin(), header_.end(), name) != header_.end();
}

size_t Table::column(std::string_view name) const {
  auto it = std::find(header_.begin(), header_.end(), name);
  if (it == header_.end()) {
    std::string present;
    for (const auto& h : header_) present += (present.empty() ? "" : ", ") + h;
    throw InputError(InputLocation::file(source_, std::nullopt, std::string(name)), "the required column is missing",
                     "columns present: " + present);
  }
  return static_cast<size_t>(it - header_.begin());
}

const std::string& Table::unitOf(size_t col) const { return units_.at(col); }

const std::string& Table::text(size_t row, size_t col) const { return rows_.at(row).at(col); }

InputLocation Table::where(size_t row, size_t col) const {
  return InputLocation::file(source_, lines_.at(row), header_.at(col));
}

double Table::number(size_t row, size_t col) const {
  const std::string& cell = text(row, col);
  double value = 0.0;
  const char* begin = cell.data();
  if (!cell.empty() && cell[0] == '+') ++begin;
  auto res = std::from_chars(begin, cell.data() + cell.size(), value);
  if (cell.empty() || res.ec != std::errc() || res.ptr != cell.data() + cell.size() || !std::isfinite(value))
    throw InputError(where(row, col), "'" + cell + "' is not a number", "a plain number such as 1.25");
  return value;
}

double Table::quantity(size_t row, size_t col, std::string_view unit) const {
  return number(row, col) * units::parseUnit(unit, where(row, col)).si;
}

bool Table::flag(size_t row, size_t col) const {
  std::string v = text(row, col);
  std::transform(v.begin(), v.end(), v.begin(), [](unsigned char c) { return std::tolower(c); });
  if (v == "1" || v == "y" || v == "yes" || v == "true") return true;
  if (v == "0" || v == "n" || v == "no" || v == "false") return false;
  throw InputError(where(row, col), "'" + text(row, col) + "' is not a yes/no value", "1/0, Y/N, yes/no, true/false");
}

}  // namespace blt::csv
