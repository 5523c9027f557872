// blt validate: the report's bookkeeping (its physics is what it reports, not what CI checks). The runs are
// handed over in runs.jsonl, as a finished earlier report leaves them, so these tests run no simulation.
#include <doctest/doctest.h>

#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "blt/sim/run_cache.hpp"
#include "run_blt.hpp"

namespace {

// The key runs.jsonl files a run under (RunCache::key): the scenario's path, the hash of its text, the model
// fingerprint, the settings.
std::string runKey(const std::string& scenario, const std::vector<std::string>& settings) {
  std::ifstream in(std::string(BLT_DATA_DIR) + "/" + scenario);
  const std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  return blt::sim::RunCache::key(scenario, text, settings);
}

// A run summary with the outer-layer and plate holes given (the two layers Table 5 names).
nlohmann::json summary(bool perforated, double outerMm, double plateMm) {
  return {{"perforated", perforated},
          {"hole_size_mm", {{outerMm, outerMm}, {5.0, 5.0}, {4.0, 4.0}, {plateMm, plateMm}}}};
}

}  // namespace

TEST_CASE("validate: Table 5 errors are against seed 000's measured holes, runs come from runs.jsonl") {
  const auto dir = std::filesystem::temp_directory_path() / "blt_validate_table5";
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  {
    std::ofstream log(dir / "runs.jsonl");
    // Cases 03 (1.4 mm, 3.02 km/s) and 05 (1.2 mm, 4.03 km/s) of seed 000 Table 1, both models.
    for (const char* model : {"original", "corrected"}) {
      const bool corrected = std::string(model) == "corrected";
      const std::string scenario = std::string("scenarios/fabric_al_") + model + ".toml";
      log << nlohmann::json{{"key", runKey(scenario, {"projectile.diameter=1.4mm", "projectile.velocity=3.02km/s",
                                                     "projectile.angle=0deg"})},
                            {"summary", summary(true, corrected ? 2.0 : 4.0, 2.1)}}
                 .dump()
          << "\n";
      log << nlohmann::json{{"key", runKey(scenario, {"projectile.diameter=1.2mm", "projectile.velocity=4.03km/s",
                                                     "projectile.angle=0deg"})},
                            {"summary", summary(true, corrected ? 1.8 : 3.6, 1.0)}}
                 .dump()
          << "\n";
    }
    log << "{\"key\": \"cut short by a kill";  // a last line left half-written must be skipped
  }
  const BltRun r = runBlt("validate --only table5 --out '" + dir.string() + "'");
  REQUIRE_MESSAGE(r.status == 0, r.output);
  CHECK(r.output.find("0 runs made, 4 reused") != std::string::npos);
  std::ifstream in(dir / "validation.json");
  const auto doc = nlohmann::json::parse(in);
  const auto& rows = doc["sections"]["table5"]["comparisons"];
  REQUIRE(rows.size() == 8);
  // Case 03 outer layer, corrected: measured 2.0 x 1.8 mm (seed 000 Table 5), mean 1.9; ours 2.0.
  CHECK(rows[1]["item"] == "case 03 outer_layer, corrected");
  CHECK(rows[1]["measured"].get<double>() == doctest::Approx(1.9));
  CHECK(rows[1]["seed_model"].get<double>() == doctest::Approx(2.55));  // 2.7 x 2.4
  CHECK(rows[1]["error"].get<double>() == doctest::Approx(0.1 / 1.9));
  CHECK(rows[1]["met"] == true);
  // Case 05 plate, corrected: measured 2.4 x 1.1 (mean 1.75), ours 1.0: -43 %, missed.
  CHECK(rows[7]["item"] == "case 05 aluminum_plate, corrected");
  CHECK(rows[7]["error"].get<double>() == doctest::Approx(1.0 / 1.75 - 1));
  CHECK(rows[7]["met"] == false);
  // Outer holes: corrected closer in both cases; plate holes: equal, so not closer.
  CHECK(doc["sections"]["table5"]["corrected_closer"] == 2);
  CHECK(std::filesystem::exists(dir / "table5_holes.svg"));
  std::ifstream md(dir / "validation.md");
  const std::string text((std::istreambuf_iterator<char>(md)), std::istreambuf_iterator<char>());
  CHECK(text.find("Numeric targets met: 3 of 4") != std::string::npos);
}

TEST_CASE("validate: an unknown section is an error naming the sections there are") {
  const BltRun r = runBlt("validate --only table9 --out '" +
                          (std::filesystem::temp_directory_path() / "blt_validate_bad").string() + "'");
  CHECK(r.status == 2);
  CHECK(r.output.find("--only") != std::string::npos);
  CHECK(r.output.find("no section 'table9'") != std::string::npos);
  CHECK(r.output.find("table1, table5, table6, table7, seed003, weldox, seed001, convergence") != std::string::npos);
}

TEST_CASE("validate: Table 1 at several grid alignments counts the right outcomes at each, offset 0 the table's") {
  const auto dir = std::filesystem::temp_directory_path() / "blt_validate_table1_alignments";
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  // Seed 000 Table 1 (data/seed/seed000_table1_tests.csv): d (mm), V (km/s), perforated in the test.
  struct Test {
    const char* d;
    const char* v;
    bool perforated;
  };
  const std::vector<Test> tests{{"1", "3.09", false}, {"1.2", "2.93", false}, {"1.4", "3.02", true},
                                {"1", "3.98", true},  {"1.2", "4.03", true},  {"0.9", "3.85", false},
                                {"1", "4.3", true},   {"0.8", "4.47", false}, {"0.8", "4.91", false},
                                {"1.2", "4.99", true}, {"1", "5.15", true},   {"0.9", "6.11", false},
                                {"1", "6.19", true}};
  {
    std::ofstream log(dir / "runs.jsonl");
    const auto put = [&](const std::string& scenario, std::vector<std::string> settings, bool perforated) {
      log << nlohmann::json{{"key", runKey(scenario, settings)}, {"summary", {{"perforated", perforated}}}}.dump() << "\n";
    };
    for (std::size_t i = 0; i < tests.size(); ++i) {
      const std::vector<std::string> shot{std::string("projectile.diameter=") + tests[i].d + "mm",
                                          std::string("projectile.velocity=") + tests[i].v + "km/s",
                                          "projectile.angle=0deg"};
      // Offset 0: all right; offset 0.5: the first three wrong. The other two models: all right.
      put("scenarios/fabric_al_corrected.toml", shot, tests[i].perforated);
      auto multi = shot;
      multi.push_back("solver.contact=multi-field");
      put("scenarios/fabric_al_corrected.toml", multi, tests[i].perforated);
      put("scenarios/fabric_al_original.toml", shot, tests[i].perforated);
      auto shifted = shot;
      shifted.push_back("resolution.grid_offset=0.5");
      put("scenarios/fabric_al_corrected.toml", shifted, i < 3 ? !tests[i].perforated : tests[i].perforated);
    }
  }
  const BltRun r = runBlt("validate --only table1 --alignments 2 --out '" + dir.string() + "'");
  REQUIRE_MESSAGE(r.status == 0, r.output);
  CHECK(r.output.find("0 runs made, 52 reused") != std::string::npos);
  std::ifstream in(dir / "validation.json");
  const auto doc = nlohmann::json::parse(in);
  const auto& table1 = doc["sections"]["table1"];
  CHECK(table1["right_corrected"] == 13);
  CHECK(table1["alignments"]["right"] == nlohmann::json::array({13, 10}));
  CHECK(table1["alignments"]["cases"][0]["right"] == 1);
  CHECK(table1["alignments"]["cases"][3]["right"] == 2);
  std::ifstream md(dir / "validation.md");
  const std::string text((std::istreambuf_iterator<char>(md)), std::istreambuf_iterator<char>());
  CHECK(text.find("Right outcomes at each alignment: 13, 10 of 13 (10 to 13)") != std::string::npos);
  CHECK(text.find("holds at 1 of 2 alignments") != std::string::npos);
}

TEST_CASE("validate: Weldox is run at two resolutions and judged on the finer, against seed 002's experiment") {
  const auto dir = std::filesystem::temp_directory_path() / "blt_validate_weldox";
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  const std::string scenario = "scenarios/weldox_10mm_blunt.toml";
  auto weldoxRun = [](double residual) {
    return nlohmann::json{{"perforated", true},
                          {"residual_velocity_m_s", residual},
                          {"residual_velocity_of", "projectile"},
                          {"wall_time_s", 1.0}};
  };
  {
    std::ofstream log(dir / "runs.jsonl");
    // The scenario's resolution (0.25 mm particles, 0.5 mm cells) and half its spacing.
    log << nlohmann::json{{"key", runKey(scenario, {})}, {"summary", weldoxRun(170.0)}}.dump() << "\n";
    log << nlohmann::json{{"key", runKey(scenario, {"resolution.particle_spacing=0.125mm",
                                                    "resolution.cell_size=0.25mm"})},
                          {"summary", weldoxRun(190.0)}}
               .dump()
        << "\n";
  }
  const BltRun r = runBlt("validate --only weldox --out '" + dir.string() + "'");
  REQUIRE_MESSAGE(r.status == 0, r.output);
  CHECK(r.output.find("0 runs made, 2 reused") != std::string::npos);
  std::ifstream in(dir / "validation.json");
  const auto doc = nlohmann::json::parse(in);
  const auto& k = doc["sections"]["weldox"]["comparisons"][0];
  CHECK(k["measured"].get<double>() == doctest::Approx(197.9));  // seed 002 ch. 5, Table 1
  CHECK(k["ours"].get<double>() == doctest::Approx(190.0));      // the finer run
  CHECK(k["seed_model"].get<double>() == doctest::Approx(206.7));  // seed 002 Table 1, 0.25 mm elements
  CHECK(k["error"].get<double>() == doctest::Approx(190.0 / 197.9 - 1));
  CHECK(k["met"] == true);
  const auto& runs = doc["sections"]["weldox"]["runs"];
  REQUIRE(runs.size() == 2);
  CHECK(runs[0]["particle_spacing_mm"].get<double>() == doctest::Approx(0.25));
  CHECK(runs[0]["residual_velocity_m_s"].get<double>() == doctest::Approx(170.0));
  CHECK(runs[0]["seed_model_m_s"].get<double>() == doctest::Approx(211.8));  // seed 002 Table 1, 0.5 mm elements
  CHECK(runs[1]["cell_size_mm"].get<double>() == doctest::Approx(0.25));
}
