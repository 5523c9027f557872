#pragma once
// The one CSV reader. Every numeric read goes through it so that a bad cell is reported with the file, the
// line, the column and the value. Lines starting with '#' and blank lines are skipped; fields may be quoted
// ("a, b"); a UTF-8 byte-order mark is ignored.

#include <string>
#include <string_view>
#include <vector>

#include "blt/core/error.hpp"
#include "blt/core/units.hpp"

namespace blt::csv {

struct ReadOptions {
  // The row after the header names each column's unit (as in the pyBLOSSUM databases: "cm", "km/s", "-").
  bool unitRow = false;
};

class Table {
 public:
  // Reads a file. Throws InputError when it cannot be opened, is empty, has no data rows, or a row has a
  // different number of fields than the header.
  static Table read(const std::string& path, const ReadOptions& options = {});
  // Parses text; `sourceName` is used in error messages in place of a path.
  static Table parse(std::string_view text, const std::string& sourceName, const ReadOptions& options = {});

  const std::string& source() const { return source_; }
  const std::vector<std::string>& header() const { return header_; }
  size_t rowCount() const { return rows_.size(); }

  bool hasColumn(std::string_view name) const;
  // Index of a column; throws InputError naming the file, the missing column and the columns present.
  size_t column(std::string_view name) const;
  // The unit named in the unit row for a column ("" for '-' or when there is no unit row).
  const std::string& unitOf(size_t col) const;

  const std::string& text(size_t row, size_t col) const;
  // A plain number (no unit in the cell). Throws InputError for anything else.
  double number(size_t row, size_t col) const;
  // A number in the unit `unit` (the column's unit, e.g. "km/s" for velocity_km_s), returned in SI.
  double quantity(size_t row, size_t col, std::string_view unit) const;
  // A yes/no flag: 1/0, Y/N, yes/no, true/false (any case).
  bool flag(size_t row, size_t col) const;

  // The 1-based line in the file of a data row, and a location for errors about a cell.
  int line(size_t row) const { return lines_[row]; }
  InputLocation where(size_t row, size_t col) const;

 private:
  std::string source_;
  std::vector<std::string> header_;
  std::vector<std::string> units_;
  std::vector<std::vector<std::string>> rows_;
  std::vector<int> lines_;
};

}  // namespace blt::csv
