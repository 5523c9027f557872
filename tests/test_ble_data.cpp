// Reading binary impact data: the project's CSV and the pyBLOSSUM databases.
#include <doctest/doctest.h>

#include <cstdio>
#include <filesystem>
#include <fstream>

#include "approx.hpp"
#include "blt/ble/impact_data.hpp"
#include "blt/core/error.hpp"

using namespace blt;

namespace {
std::string writeTemp(const std::string& name, const std::string& text) {
  const auto path = (std::filesystem::temp_directory_path() / name).string();
  std::ofstream(path) << text;
  return path;
}
}  // namespace

TEST_CASE("ble data: seed 000 Table 1 reads as 13 binary points in SI") {
  const auto pts = ble::readImpactCsv(std::string(BLT_DATA_DIR) + "/seed/seed000_table1_tests.csv");
  REQUIRE(pts.size() == 13);
  // Test 03 of seed 000 Table 1: 1.4 mm at 3.02 km/s, perforated.
  CHECK(pts[2].diameter == relApprox(1.4e-3));
  CHECK(pts[2].velocity == relApprox(3020.0));
  CHECK(pts[2].perforated);
  CHECK_FALSE(pts[0].perforated);
  CHECK(pts[0].projectileDensity == 0.0);  // the file gives none; the fit's --density applies
}

TEST_CASE("ble data: bad rows give errors naming file, line and field") {
  const std::string header = "diameter_mm,velocity_km_s,angle_deg,perforated,source\n";
  CHECK_THROWS_WITH_AS(ble::readImpactCsv(writeTemp("blt_nan.csv", header + "1.0,nan,0,1,x\n")),
                       doctest::Contains("line 2, field 'velocity_km_s': 'nan' is not a number"), InputError);
  CHECK_THROWS_WITH_AS(ble::readImpactCsv(writeTemp("blt_neg.csv", header + "-1.0,3,0,1,x\n")),
                       doctest::Contains("field 'diameter_mm': '-1.0' is not a positive diameter"), InputError);
  CHECK_THROWS_WITH_AS(ble::readImpactCsv(writeTemp("blt_ang.csv", header + "1.0,3,95,1,x\n")),
                       doctest::Contains("angle 95 is outside the range (allowed: 0 <= angle < 90 deg)"), InputError);
  CHECK_THROWS_WITH_AS(ble::readImpactCsv(writeTemp("blt_flag.csv", header + "1.0,3,0,maybe,x\n")),
                       doctest::Contains("field 'perforated': 'maybe' is not a yes/no value"), InputError);
  CHECK_THROWS_WITH_AS(ble::readImpactCsv(writeTemp("blt_col.csv", "diameter_mm,velocity_km_s,perforated\n1,3,1\n")),
                       doctest::Contains("field 'angle_deg': the required column is missing"), InputError);
  CHECK_THROWS_WITH_AS(ble::readImpactCsv(writeTemp("blt_empty.csv", "")), doctest::Contains("the file is empty"),
                       InputError);
}

TEST_CASE("ble data: a pyBLOSSUM filter selects one Whipple configuration") {
  const std::string path = std::string(BLT_SHARED_DIR) + "/data/pyblossum/database_whipple_pyBLOSSUM.csv";
  REQUIRE(std::filesystem::exists(path));
  // Counted independently with awk on the file: 84 shots on 0.16 cm AA6061-T6 bumper, 10.16 cm standoff,
  // 0.318 cm AA2219-T87 wall; 58 of them perforated.
  const auto pts = ble::readPyblossum(
      path, {ble::ColumnCondition::parse("bumper_mat=AA6061-T6", "--where"), ble::ColumnCondition::parse("bumper_thick=1.6mm", "--where"),
             ble::ColumnCondition::parse("standoff=10.16cm", "--where"), ble::ColumnCondition::parse("wall_mat=AA2219-T87", "--where"),
             ble::ColumnCondition::parse("wall_thick=0.318 cm", "--where")});
  CHECK(pts.size() == 84);
  int perforated = 0;
  for (const auto& p : pts) perforated += p.perforated;
  CHECK(perforated == 58);
  CHECK(pts[0].projectileDensity > 1000.0);  // g/cm3 in the file, SI here
  CHECK_THROWS_WITH_AS(ble::readPyblossum(path, {ble::ColumnCondition::parse("wall_thick=3 km/s", "--where")}),
                       doctest::Contains("is a velocity, the column a length"), InputError);
  CHECK_THROWS_WITH_AS(ble::readPyblossum(path, {ble::ColumnCondition::parse("no_such=1", "--where")}),
                       doctest::Contains("field 'no_such': the required column is missing"), InputError);
  CHECK_THROWS_WITH_AS(ble::readPyblossum(path, {ble::ColumnCondition::parse("wall_thick=99cm", "--where")}),
                       doctest::Contains("no shot meets"), InputError);
  CHECK_THROWS_AS(ble::ColumnCondition::parse("wall_thick", "--where"), InputError);
}
