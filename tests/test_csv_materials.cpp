// The CSV reader and the material library: the errors a user sees for bad files.
#include <doctest/doctest.h>

#include "approx.hpp"

#include "blt/core/csv.hpp"
#include "blt/core/materials.hpp"

using namespace blt;

TEST_CASE("csv: reads columns, units, flags and skips comments") {
  auto t = csv::Table::parse(
      "# seed 000 Table 1 excerpt\n"
      "diameter_mm,velocity_km_s,angle_deg,perforated,source\n"
      "1.0,3.09,0,N,\"test 01, seed 000\"\n"
      "\n"
      "1.2,4.99,0,Y,test 10\n",
      "mem.csv");
  REQUIRE(t.rowCount() == 2);
  CHECK(t.quantity(0, t.column("diameter_mm"), "mm") == relApprox(1.0e-3));
  CHECK(t.quantity(1, t.column("velocity_km_s"), "km/s") == relApprox(4990.0));
  CHECK(t.flag(1, t.column("perforated")));
  CHECK_FALSE(t.flag(0, t.column("perforated")));
  CHECK(t.text(0, t.column("source")) == "test 01, seed 000");
  CHECK(t.line(1) == 5);
}

TEST_CASE("csv: bad input gives errors naming file, line and column") {
  CHECK_THROWS_WITH_AS(csv::Table::parse("", "empty.csv"), doctest::Contains("empty.csv: the file is empty"), InputError);
  CHECK_THROWS_WITH_AS(csv::Table::parse("a,b\n", "hdr.csv"), doctest::Contains("no data rows"), InputError);
  CHECK_THROWS_WITH_AS(csv::Table::read("/nonexistent/x.csv"), doctest::Contains("cannot open"), InputError);
  auto t = csv::Table::parse("a,b\n1,x\n", "t.csv");
  CHECK_THROWS_WITH_AS(t.column("velocity_km_s"),
                       doctest::Contains("field 'velocity_km_s': the required column is missing (allowed: columns present: a, b)"),
                       InputError);
  CHECK_THROWS_WITH_AS(t.number(0, 1), doctest::Contains("file t.csv, line 2, field 'b': 'x' is not a number"),
                       InputError);
  CHECK_THROWS_WITH_AS(t.flag(0, 0) && t.flag(0, 1), doctest::Contains("not a yes/no value"), InputError);
  CHECK_THROWS_WITH_AS(csv::Table::parse("a,b\n1,2,3\n", "w.csv"), doctest::Contains("line 2: the row has 3 fields"),
                       InputError);
}

TEST_CASE("csv: a unit row as in the pyBLOSSUM databases") {
  auto t = csv::Table::parse("\xEF\xBB\xBFproj_diam,velocity\ncm,km/s\n0.14,9.89\n", "db.csv", {.unitRow = true});
  CHECK(t.unitOf(0) == "cm");
  CHECK(t.quantity(0, 0, t.unitOf(0)) == relApprox(1.4e-3));
}

TEST_CASE("materials: a card parses with units, and bad cards are clear errors") {
  const std::string good =
      "name = \"test alloy\"\nsource = \"seed 000 Table 3\"\ndensity = \"2.77e-3 g/mm3\"\n"
      "[strength]\nmodel = \"johnson-cook\"\nA = \"265 MPa\"\nn = 0.34\n";
  Material m = parseMaterial(good, "alloy.toml", "alloy");
  CHECK(m.density == relApprox(2770.0));
  CHECK(m.param("strength", "A") == relApprox(265e6));
  CHECK_THROWS_WITH_AS(m.param("strength", "B"), doctest::Contains("strength.B"), InputError);
  CHECK_THROWS_WITH_AS(parseMaterial("name=\"x\"\nsource=\"y\"\ndensity=\"2770\"\n", "a.toml", "a"),
                       doctest::Contains("line 3, field 'density': '2770' has no unit"), InputError);
  CHECK_THROWS_WITH_AS(parseMaterial(good + "B = 426\n", "b.toml", "b"),
                       doctest::Contains("line 8, field 'strength.B': the number"), InputError);
  CHECK_THROWS_WITH_AS(parseMaterial(good + "Q = \"1 MPa\"\n", "c.toml", "c"),
                       doctest::Contains("field 'strength.Q': unknown parameter"), InputError);
  CHECK_THROWS_WITH_AS(parseMaterial("name=\"x\"\nsource=\"y\"\ndensity=\"1 kg/m3\"\n[eos]\nmodel=\"ideal-gas\"\n",
                                     "d.toml", "d"),
                       doctest::Contains("unknown model 'ideal-gas' (allowed: mie-grueneisen, polynomial)"), InputError);
  // A card written back reads to the same values.
  Material again = parseMaterial(materialToToml(m), "again.toml", "again");
  CHECK(again.param("strength", "A") == relApprox(265e6));
  CHECK(again.param("strength", "n") == relApprox(0.34));
}

TEST_CASE("materials: notes survive a round trip, multi-line ones included") {
  const std::string text =
      "name = \"x\"\nsource = \"seed 000 Table 3\"\nnotes = \"\"\"room temperature 293 K assumed;\n\"quoted\" here\"\"\"\n"
      "density = \"2770 kg/m3\"\n";
  Material m = parseMaterial(text, "n.toml", "n");
  CHECK(m.notes == "room temperature 293 K assumed;\n\"quoted\" here");
  Material again = parseMaterial(materialToToml(m), "again.toml", "again");
  CHECK(again.notes == m.notes);
}
