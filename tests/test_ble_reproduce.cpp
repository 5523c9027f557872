// A stored fit can be reproduced from what the store holds (issue 3): the points and options loaded back give
// the same coefficients, covariance and metrics, bit for bit, and the same data hash.
#include <doctest/doctest.h>

#include <filesystem>
#include <unistd.h>

#include "blt/ble/fit.hpp"
#include "blt/ble/impact_data.hpp"
#include "blt/ble/store.hpp"
#include "run_blt.hpp"

using namespace blt;

TEST_CASE("ble store: a fit re-run from the stored points and options reproduces the stored result") {
  const std::string seed = std::string(BLT_DATA_DIR);
  std::vector<ble::ImpactPoint> points;
  for (const char* file : {"/seed/seed000_table1_tests.csv", "/examples/seed000_table6_7to9kms.csv",
                           "/seed/seed000_table7_mpm.csv"}) {
    const auto part = ble::readImpactCsv(seed + file);
    points.insert(points.end(), part.begin(), part.end());
  }
  ble::FitOptions options;  // two-stage with the default hinge
  options.defaultProjectileDensity = 2770.0;
  const std::string path =
      (std::filesystem::temp_directory_path() / ("blt_reproduce_" + std::to_string(::getpid()) + ".db")).string();
  std::filesystem::remove(path);
  {
    ble::BleStore store(path);
    ble::StoredFit fit;
    fit.name = "seed000";
    fit.options = options;
    fit.result = ble::fitChristiansen(points, options);
    fit.points = points;
    fit.dataOrigin = "seed 000 Tables 1, 6 (7-9 km/s), 7";
    fit.dataHash = ble::hashPoints(points);
    fit.toolVersion = BLT_VERSION;
    store.saveFit(fit, false);
  }
  const ble::BleStore reopened(path);
  const ble::StoredFit stored = reopened.loadFit("seed000");
  const ble::FitResult again = ble::fitChristiansen(stored.points, stored.options);
  CHECK(ble::hashPoints(stored.points) == stored.dataHash);
  CHECK(again.coefficients.toArray() == stored.result.coefficients.toArray());
  CHECK(again.covariance == stored.result.covariance);
  CHECK(again.meanSquareError == stored.result.meanSquareError);
  CHECK(again.misclassified == stored.result.misclassified);
  CHECK(again.pointCount == stored.result.pointCount);
  std::filesystem::remove(path);
}

TEST_CASE("ble CLI: fit, query with a shot's margin, list, and a refused duplicate name") {
  const std::string db =
      (std::filesystem::temp_directory_path() / ("blt_cli_" + std::to_string(::getpid()) + ".db")).string();
  std::filesystem::remove(db);
  const std::string data = std::string(BLT_DATA_DIR);
  const std::string fit = "ble fit '" + data + "/seed/seed000_table1_tests.csv' '" + data +
                          "/examples/seed000_table6_7to9kms.csv' '" + data + "/seed/seed000_table7_mpm.csv' --db '" +
                          db + "' --name seed000 --density 2770kg/m3";
  BltRun run = runBlt(fit + " --json");
  REQUIRE(run.status == 0);
  CHECK(run.output.find("\"n_points\": 63") != std::string::npos);
  // Seed 000 Table 1 test 11: 1.0 mm at 5.15 km/s perforated the plate, so its margin must be positive.
  run = runBlt("ble query --db '" + db + "' --name seed000 --velocity 5.15km/s --diameter 1.0mm --json");
  REQUIRE(run.status == 0);
  CHECK(run.output.find("\"perforation_expected\": true") != std::string::npos);
  // Test 12: 0.9 mm at 6.11 km/s did not.
  run = runBlt("ble query --db '" + db + "' --name seed000 --velocity 6.11km/s --diameter 0.9mm --json");
  CHECK(run.output.find("\"perforation_expected\": false") != std::string::npos);
  run = runBlt("ble list --db '" + db + "'");
  CHECK(run.output.find("seed000") != std::string::npos);
  run = runBlt(fit);
  CHECK(run.status == 2);
  CHECK(run.output.find("already exists") != std::string::npos);
  CHECK(run.output.find("--replace to overwrite") != std::string::npos);
  run = runBlt("ble query --db '" + db + "' --name nope --velocity 7km/s");
  CHECK(run.status == 2);
  CHECK(run.output.find("there is no fit named 'nope' (allowed: one of: seed000)") != std::string::npos);
  std::filesystem::remove(db);
}
