// Laminate equivalent model of the MLI (seed 000 §3): hand-computable stacks, the recovered MLI stacking
// against seed 000 Table 4, the equivalent material card, and the errors a user sees for bad stack files.
#include <doctest/doctest.h>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>

#include "blt/analytic/laminate.hpp"
#include "blt/core/materials.hpp"

using namespace blt;
using namespace blt::analytic;
using doctest::Approx;

namespace {

LayerMaterial material(std::string name, double eMPa, double nu, double yieldMPa, double etMPa, double ef) {
  return {std::move(name), eMPa * 1e6, nu, yieldMPa * 1e6, etMPa * 1e6, ef};
}

// Seed 000 Table 2: single layers of the MLI.
const LayerMaterial film = material("aluminized film", 2478.9, 0.2, 58, 114, 0.11);
const LayerMaterial filmWithGauze = material("aluminized film with gauze", 294, 0.2, 6.5, 109, 0.15);
const LayerMaterial gauze = material("gauze", 33.17, 0.1, 2.0, 11.7, 0.28);

// Seed 000 Table 4, MLI column; thickness from seed 000 §5.
constexpr double table4E = 261.27e6, table4Nu = 0.195, table4Yield = 5.54e6, table4Et = 66.73e6, table4Ef = 0.11;
constexpr double mliThickness = 1.0e-3;

std::string stackPath() { return std::string(BLT_DATA_DIR) + "/materials/mli_stack.toml"; }

// An independent check of the event bookkeeping: explicit small strain steps, a layer switching state at the
// first step where it is past its limit, and N_y driven back to zero every step. Returns N_x/t at `strain`.
double bruteForceStress(const std::vector<Layer>& layers, double strain, double step = 1e-6) {
  const size_t n = layers.size();
  std::vector<int> state(n, 0);  // 0 elastic, 1 yielded, 2 failed
  std::vector<double> sx(n, 0), sy(n, 0);
  double t = 0;
  for (const auto& l : layers) t += l.thickness;
  for (double ex = 0; ex < strain - step / 2; ex += step) {
    std::vector<double> q11(n), q12(n);
    double a11 = 0, a12 = 0, ny = 0;
    for (size_t k = 0; k < n; ++k) {
      const LayerMaterial& m = layers[k].material;
      const double f = state[k] == 0 ? 1.0 : state[k] == 1 ? m.tangentModulus / m.youngsModulus : 0.0;
      q11[k] = f * m.youngsModulus / (1 - m.poissonRatio * m.poissonRatio);
      q12[k] = m.poissonRatio * q11[k];
      a11 += layers[k].thickness * q11[k];
      a12 += layers[k].thickness * q12[k];
      ny += layers[k].thickness * sy[k];
    }
    if (a11 <= 0) return 0;
    const double dey = -(a12 * step + ny) / a11;
    for (size_t k = 0; k < n; ++k) {
      sx[k] += q11[k] * step + q12[k] * dey;
      sy[k] += q12[k] * step + q11[k] * dey;
      const LayerMaterial& m = layers[k].material;
      if (state[k] == 0 && sx[k] * sx[k] + sy[k] * sy[k] - sx[k] * sy[k] >= m.yieldStress * m.yieldStress)
        state[k] = 1;
      if (state[k] != 2 && ex + step >= m.failureStrain) {
        state[k] = 2;
        sx[k] = sy[k] = 0;
      }
    }
  }
  double nx = 0;
  for (size_t k = 0; k < n; ++k) nx += layers[k].thickness * sx[k];
  return nx / t;
}

std::string tempPath(const std::string& name) {
  return (std::filesystem::temp_directory_path() / ("blt_test_laminate_" + name)).string();
}

const std::string goodLayer =
    "[[layer]]\nmaterial = \"gauze\"\nthickness = \"0.1 mm\"\nyoungs_modulus = \"33.17 MPa\"\npoisson_ratio = 0.1\n"
    "yield_stress = \"2 MPa\"\ntangent_modulus = \"11.7 MPa\"\nfailure_strain = 0.28\n";
const std::string header = "name = \"test stack\"\nsource = \"seed 000 Table 2\"\n";

}  // namespace

TEST_CASE("laminate: a single isotropic layer has its own E and nu and yields at its yield stress") {
  // Hand computation: one layer under uniaxial stress is the layer itself; its bilinear curve is E up to
  // sigma_y, then E_t up to eps_f.
  const LayerMaterial m = material("plate", 70000, 0.3, 100, 1000, 0.05);
  const LaminateResponse r = analyseLaminate({{m, 2e-3, 0}});
  CHECK(r.elastic.youngsModulus == Approx(70e9).epsilon(1e-12));
  CHECK(r.elastic.poissonRatio == Approx(0.3).epsilon(1e-12));
  CHECK(r.elastic.thickness == Approx(2e-3));
  CHECK(r.firstYieldStress == Approx(100e6).epsilon(1e-10));
  CHECK(r.firstYieldStrain == Approx(100.0 / 70000).epsilon(1e-10));
  // Only one yield point: the tangent line starts at a and its slope is the layer's E_t.
  CHECK(r.tangentFrom == "a (first yield)");
  CHECK(r.tangentModulus == Approx(1e9).epsilon(1e-10));
  CHECK(r.failureStrain == Approx(0.05));
  CHECK(r.limitStress == Approx(100e6 + 1e9 * (0.05 - 100.0 / 70000)).epsilon(1e-10));
  REQUIRE(r.events.size() == 2);
  CHECK(r.events[1].stressAfter == 0.0);
}

TEST_CASE("laminate: two layers of equal nu follow the rule of mixtures, incrementally") {
  // Hand computation. With equal nu every layer is in uniaxial stress, so the laminate is the thickness-
  // weighted mean of the layers' own bilinear curves: E = (100*1 + 50*3)/4 = 62.5 MPa; layer 1 yields at
  // 1 %, layer 2 at 2 %, layer 1 fails at 5 %, layer 2 at 8 %.
  const LayerMaterial stiff = material("stiff", 100, 0.25, 1, 10, 0.05);
  const LayerMaterial soft = material("soft", 50, 0.25, 1, 5, 0.08);
  const std::vector<Layer> layers = {{stiff, 1e-3, 0}, {soft, 3e-3, 0}};
  const LaminateResponse r = analyseLaminate(layers);
  CHECK(r.elastic.youngsModulus == Approx(62.5e6).epsilon(1e-12));
  CHECK(r.elastic.poissonRatio == Approx(0.25).epsilon(1e-12));
  CHECK(r.firstYieldStrain == Approx(0.01));
  CHECK(r.firstYieldStress == Approx(0.625e6));
  // Slopes: (10*1 + 50*3)/4 = 40 MPa from 1 % to 2 %, (10*1 + 5*3)/4 = 6.25 MPa from 2 % to 5 %.
  CHECK(r.stressAt(0.02) == Approx(1.025e6));
  CHECK(r.tangentFrom == "b (second yield)");
  CHECK(r.tangentModulus == Approx(6.25e6));
  // sigma_d = 1.025 + 6.25 * 0.03 = 1.2125 MPa. Computing the layer stresses from the total strain with the
  // weakened stiffness (not incrementally) would give (10*0.05*1 + 5*0.05*3)/4 = 0.3125 MPa instead.
  CHECK(r.limitStress == Approx(1.2125e6));
  CHECK(r.failureStrain == Approx(0.05));
  // Layer 1 carried 1 + 10*0.04 = 1.4 MPa over 1 of 4 mm: the drop is 0.35 MPa; then 3.75 MPa slope to 8 %.
  CHECK(r.events[2].stressAfter == Approx(0.8625e6));
  CHECK(r.stressAt(0.08) == Approx(0.975e6));
  CHECK(r.peakStress == Approx(1.2125e6));
}

TEST_CASE("laminate: the MLI curve is continuous between failures, ordered, and matches small-step integration") {
  const Stack stack = loadStack(stackPath());
  const LaminateResponse r = analyseLaminate(stack.layers);
  REQUIRE(r.curve.size() >= 2);
  for (size_t i = 1; i < r.curve.size(); ++i) {
    CHECK(r.curve[i].strain >= r.curve[i - 1].strain);
    // Equal strains only at a failure, where the second point is the stress after the drop.
    if (r.curve[i].strain == r.curve[i - 1].strain) {
      CHECK(r.curve[i].event.rfind("after failure", 0) == 0);
      CHECK(r.curve[i].stress < r.curve[i - 1].stress);
    }
  }
  for (size_t i = 1; i < r.events.size(); ++i) CHECK(r.events[i].strain >= r.events[i - 1].strain);
  // Every layer yields once and fails once.
  CHECK(r.events.size() == 2 * stack.layers.size());
  // Before the first ply failure there is no drop: each yield event has the same stress before and after.
  for (const auto& e : r.events)
    if (e.kind == LayerEventKind::yield) CHECK(e.stressAfter == e.stress);
  // Independent explicit integration (steps of 1e-6 strain): agrees to 1e-4 of the stress.
  for (double strain : {0.01, 0.022, 0.03, 0.05, 0.07, 0.1, 0.12, 0.2, 0.27}) {
    CAPTURE(strain);
    const double brute = bruteForceStress(stack.layers, strain);
    CHECK(r.stressAt(strain) == Approx(brute).epsilon(1e-4));
  }
}

TEST_CASE("laminate: the recovered MLI stacking reproduces seed 000 Table 4") {
  // Recovery from seed 000 Table 2 layers and the Table 4 targets.
  const StackRecovery rec = recoverStacking({film, filmWithGauze, gauze}, {table4E, table4Nu, mliThickness});
  MESSAGE("recovered totals: film " << rec.totalThickness[0] * 1e3 << " mm, film with gauze "
                                    << rec.totalThickness[1] * 1e3 << " mm, gauze " << rec.totalThickness[2] * 1e3
                                    << " mm (" << rec.evaluations << " evaluations)");
  CHECK(rec.achieved.youngsModulus == Approx(table4E).epsilon(0.01));
  CHECK(std::abs(rec.achieved.poissonRatio - table4Nu) < 0.005);
  CHECK(rec.achieved.thickness == Approx(mliThickness).epsilon(1e-6));
  for (double ti : rec.totalThickness) CHECK(ti >= 0);

  // The shipped stack file is that recovery laid out on 9 layers: same totals, same predictions.
  const Stack stack = loadStack(stackPath());
  CHECK(stack.layers.size() == 9);
  const std::vector<LayerMaterial> kinds = distinctMaterials(stack.layers);
  REQUIRE(kinds.size() == 3);
  for (size_t i = 0; i < kinds.size(); ++i) {
    double total = 0;
    for (const auto& l : stack.layers)
      if (l.material.name == kinds[i].name) total += l.thickness;
    for (size_t j = 0; j < rec.materials.size(); ++j)
      if (rec.materials[j].name == kinds[i].name) CHECK(total == Approx(rec.totalThickness[j]).epsilon(1e-6));
  }

  const LaminateResponse r = analyseLaminate(stack.layers);
  MESSAGE("MLI vs seed 000 Table 4: E " << r.elastic.youngsModulus / 1e6 << " MPa (261.27), nu "
                                        << r.elastic.poissonRatio << " (0.195), yield " << r.firstYieldStress / 1e6
                                        << " MPa (5.54), E_t " << r.tangentModulus / 1e6 << " MPa (66.73), eps_f "
                                        << r.failureStrain << " (0.11), limit " << r.limitStress / 1e6 << " MPa");
  CHECK(r.elastic.youngsModulus == Approx(table4E).epsilon(0.01));
  CHECK(std::abs(r.elastic.poissonRatio - table4Nu) < 0.005);
  CHECK(r.firstYieldStress == Approx(table4Yield).epsilon(0.05));
  // The first ply failure is the film's failure strain (Table 2), which Table 4 quotes as the MLI's.
  CHECK(r.failureStrain == Approx(table4Ef).epsilon(1e-9));
  // Three distinct yield points a, b, c before d, as in seed 000 Fig. 9 (film with gauze, film, gauze).
  int yieldKinks = 0;
  double last = -1;
  for (const auto& e : r.events)
    if (e.kind == LayerEventKind::yield && e.strain > last) {
      ++yieldKinks;
      last = e.strain;
    }
  CHECK(yieldKinks == 3);
  CHECK(r.tangentFrom == "b (second yield)");
  // E_t is NOT tested against Table 4: the model gives ~73.3 MPa vs 66.73 MPa (+9.8 %), and no stacking that
  // matches E and nu can change that much (E_t is then fixed, see the header of recoverStacking).
  MESSAGE("E_t relative deviation from Table 4: " << r.tangentModulus / table4Et - 1);
}

TEST_CASE("laminate: the equivalent card is a library material that loads back") {
  const Stack stack = loadStack(stackPath());
  const LaminateResponse r = analyseLaminate(stack.layers);
  const Material card = equivalentMaterialCard(stack, r, "mli_laminate");
  const std::string path = tempPath("card.toml");
  {
    std::ofstream out(path);
    out << materialToToml(card);
  }
  const Material back = loadMaterial(path);
  std::remove(path.c_str());
  CHECK(back.density == Approx(267.0));  // seed 000 Table 4: 0.267e-3 g/mm3
  CHECK(back.param("elastic", "youngs_modulus") == Approx(r.elastic.youngsModulus).epsilon(1e-7));
  CHECK(back.param("elastic", "poisson_ratio") == Approx(r.elastic.poissonRatio).epsilon(1e-7));
  CHECK(back.section("strength").model == "bilinear");
  CHECK(back.param("strength", "yield_stress") == Approx(r.firstYieldStress).epsilon(1e-7));
  CHECK(back.param("strength", "tangent_modulus") == Approx(r.tangentModulus).epsilon(1e-7));
  CHECK(back.section("failure").model == "max-principal-strain");
  CHECK(back.param("failure", "max_principal_strain") == Approx(0.11));
  CHECK(back.section("eos").model == "mie-grueneisen");
  CHECK(back.param("eos", "c0") == Approx(2000.0));
  CHECK(back.param("eos", "s") == Approx(1.4));
  CHECK(back.param("eos", "gamma0") == Approx(1.53));

  Stack bare = stack;
  bare.card.reset();
  CHECK_THROWS_WITH_AS(equivalentMaterialCard(bare, r, "x"), doctest::Contains("field 'card'"), InputError);
}

TEST_CASE("laminate: a stack file round-trips through stackToToml") {
  const Stack stack = loadStack(stackPath());
  const Stack again = parseStack(stackToToml(stack, "comment line"), "again.toml");
  REQUIRE(again.layers.size() == stack.layers.size());
  for (size_t i = 0; i < stack.layers.size(); ++i) {
    CHECK(again.layers[i].thickness == Approx(stack.layers[i].thickness).epsilon(1e-7));
    CHECK(again.layers[i].material.name == stack.layers[i].material.name);
  }
  CHECK(again.notes == stack.notes);
  REQUIRE(again.card);
  CHECK(again.card->c0 == Approx(2000.0));
}

TEST_CASE("laminate: bad stack files name the file, line, key and what is allowed") {
  auto parse = [](const std::string& text) { return parseStack(text, "stack.toml"); };
  // Layer 2's thickness is on line 14 of the text below.
  CHECK_THROWS_WITH_AS(parse(header + goodLayer + "\n" + [] {
                         std::string l = goodLayer;
                         return l.replace(l.find("\"0.1 mm\""), 8, "\"-0.1 mm\"");
                       }()),
                       doctest::Contains("file stack.toml, line 14, field 'layer[2].thickness': the value -0.1 mm is "
                                         "out of range (allowed: a positive thickness)"),
                       InputError);
  CHECK_THROWS_WITH_AS(parse(header + [] {
                         std::string l = goodLayer;
                         return l.replace(l.find("\"0.1 mm\""), 8, "0.1");
                       }()),
                       doctest::Contains("line 5, field 'layer[1].thickness': the number 0.1 has no unit"),
                       InputError);
  CHECK_THROWS_WITH_AS(parse(header + [] {
                         std::string l = goodLayer;
                         return l.replace(l.find("failure_strain = 0.28"), 21, "failure_strain = 0");
                       }()),
                       doctest::Contains("field 'layer[1].failure_strain': the value 0 is out of range (allowed: a "
                                         "failure strain > 0)"),
                       InputError);
  CHECK_THROWS_WITH_AS(parse(header + [] {
                         std::string l = goodLayer;
                         return l.replace(l.find("yield_stress"), 22, "");
                       }()),
                       doctest::Contains("file stack.toml, line 3, field 'layer[1].yield_stress': the required key is "
                                         "missing"),
                       InputError);
  CHECK_THROWS_WITH_AS(parse(header), doctest::Contains("field 'layer': the required key is missing"), InputError);
  CHECK_THROWS_WITH_AS(parse("source = \"x\"\n" + goodLayer), doctest::Contains("field 'name': the required key"),
                       InputError);
  CHECK_THROWS_WITH_AS(parse(header + goodLayer + "colour = \"grey\"\n"),
                       doctest::Contains("line 11, field 'layer[1].colour': unknown key (allowed: material, thickness"),
                       InputError);
  CHECK_THROWS_WITH_AS(parse(header + goodLayer + "\n" + [] {
                         std::string l = goodLayer;
                         return l.replace(l.find("\"33.17 MPa\""), 11, "\"40 MPa\"");
                       }()),
                       doctest::Contains("field 'layer[2].material': material 'gauze' has other properties than in "
                                         "layer 1"),
                       InputError);
  CHECK_THROWS_WITH_AS(parse(header + [] {
                         std::string l = goodLayer;
                         return l.replace(l.find("poisson_ratio = 0.1"), 19, "poisson_ratio = 0.6");
                       }()),
                       doctest::Contains("field 'layer[1].poisson_ratio': the value 0.6 is out of range (allowed: -1 < "
                                         "nu < 0.5)"),
                       InputError);
  CHECK_THROWS_WITH_AS(parse(header + goodLayer + "[card]\nname = \"c\"\nsource = \"s\"\ndensity = 267\n"),
                       doctest::Contains("field 'card.density': the number 267 has no unit"), InputError);
  CHECK_THROWS_WITH_AS(loadStack("/nonexistent/stack.toml"),
                       doctest::Contains("file /nonexistent/stack.toml: cannot open the stack file"), InputError);
  // A good file parses.
  const Stack s = parse(header + goodLayer);
  CHECK(s.layers.size() == 1);
  CHECK(s.layers[0].thickness == Approx(1e-4));
}
