// blt analytic laminate: the laminate equivalent model of the MLI (seed 000 §3). Reads a stack file, prints
// the equivalent E, nu, yield stress, tangent modulus, limit stress and failure strain, and optionally writes
// the stress-strain curve and the equivalent material card. With --recover it first re-fits the thickness of
// each material to target E, nu and t (seed 000 Table 4 by default), which is how
// data/materials/mli_stack.toml is regenerated.
#include <filesystem>
#include <fstream>
#include <iomanip>
#include <memory>
#include <sstream>

#include "blt/analytic/laminate.hpp"
#include "blt/core/materials.hpp"
#include "cli_support.hpp"
#include "commands.hpp"

namespace blt::cli {

namespace {

using namespace blt::analytic;

struct LaminateOptions {
  std::string stackPath;
  std::string curvePath;
  std::string cardPath;
  bool json = false;
  bool recover = false;
  std::string writeStackPath;
  // Seed 000 Table 4, MLI column, and the MLI thickness of seed 000 §5.
  StackTarget target{261.27e6, 0.195, 1.0e-3};
};

std::ofstream openOutput(const std::string& path, const std::string& flag) {
  std::ofstream out(path);
  if (!out) throw InputError(InputLocation::flag(flag), "cannot write '" + path + "'", "a writable file path");
  return out;
}

std::string csvField(const std::string& s) {
  if (s.find_first_of(",\"") == std::string::npos) return s;
  std::string q = "\"";
  for (char ch : s) q += ch == '"' ? std::string("\"\"") : std::string(1, ch);
  return q + "\"";
}

std::string eventKind(LayerEventKind k) { return k == LayerEventKind::yield ? "yield" : "failure"; }

std::string recoveryComment(const Stack& stack, const StackRecovery& rec, const StackTarget& target,
                            const LaminateResponse& response) {
  std::ostringstream c;
  c << "Layer stacking of the MLI blanket of seed 000 (Fig. 6-7: 9 layers, symmetric), recovered because the\n"
    << "seed does not give the layer thicknesses. Single-layer properties: seed 000 Table 2.\n"
    << "\n"
    << "Regenerate with:\n"
    << "  blt analytic laminate data/materials/mli_stack.toml --recover --write-stack data/materials/mli_stack.toml\n"
    << "How: only the in-plane stiffness A = sum t_k Q_k enters (no bending), so E and nu depend on the total\n"
    << "thickness of each material, not on the order or the split into layers. " << rec.algorithm << " found\n"
    << "the totals (bounded to [0, t]) that match the targets E = " << units::format(target.youngsModulus, "MPa")
    << ", nu = " << target.poissonRatio << ", t = " << units::format(target.thickness, "mm") << "\n"
    << "(seed 000 Table 4 MLI column; t from seed 000 §5) in " << rec.evaluations << " evaluations:\n";
  for (size_t i = 0; i < rec.materials.size(); ++i)
    c << "  " << rec.materials[i].name << ": " << units::format(rec.totalThickness[i], "mm", 5) << " in total\n";
  c << "Residuals: E/E* - 1 = " << std::setprecision(3) << rec.residualModulus
    << ", nu - nu* = " << rec.residualPoisson << ", t/t* - 1 = " << rec.residualThickness << ".\n"
    << "Each material's total is split equally among its layers below; the layer order is a modelling choice\n"
    << "(it does not change A). The plastic figures are predictions, not fitted: first yield "
    << units::format(response.firstYieldStress, "MPa", 4) << ",\n"
    << "tangent modulus (line " << response.tangentFrom.substr(0, 1) << "-d) " << units::format(response.tangentModulus, "MPa", 4)
    << ", limit stress " << units::format(response.limitStress, "MPa", 4) << ", failure strain "
    << response.failureStrain << ".\nSee them with: blt analytic laminate data/materials/mli_stack.toml\n";
  if (stack.card) c << "[card]: what the equivalent material card needs beyond the laminate model.\n";
  return c.str();
}

void run(const LaminateOptions& o) {
  Stack stack = loadStack(o.stackPath);
  std::optional<StackRecovery> recovery;
  if (o.recover) {
    recovery = recoverStacking(distinctMaterials(stack.layers), o.target);
    stack.layers = layOut(stack.layers, *recovery);
    if (!o.writeStackPath.empty()) {
      const std::string text =
          stackToToml(stack, recoveryComment(stack, *recovery, o.target, analyseLaminate(stack.layers)));
      // Check the file reads back before replacing anything.
      (void)parseStack(text, o.writeStackPath);
      openOutput(o.writeStackPath, "--write-stack") << text;
    }
  }
  const LaminateResponse r = analyseLaminate(stack.layers);

  if (!o.curvePath.empty()) {
    std::ofstream out = openOutput(o.curvePath, "--curve");
    out << "strain,stress_MPa,event\n" << std::setprecision(10);
    for (const auto& p : r.curve) out << p.strain << "," << p.stress * 1e-6 << "," << csvField(p.event) << "\n";
  }
  if (!o.cardPath.empty()) {
    const Material card =
        equivalentMaterialCard(stack, r, std::filesystem::path(o.cardPath).stem().string());
    openOutput(o.cardPath, "--card") << "# Written by: blt analytic laminate " << o.stackPath << " --card "
                                     << o.cardPath << "\n"
                                     << materialToToml(card);
  }

  if (o.json) {
    nlohmann::json events = nlohmann::json::array();
    for (const auto& e : r.events)
      events.push_back({{"kind", eventKind(e.kind)},
                        {"layer_number", e.layer + 1},
                        {"material", e.material},
                        {"strain", e.strain},
                        {"stress_Pa", e.stress},
                        {"stress_after_Pa", e.stressAfter}});
    nlohmann::json doc = {{"stack", o.stackPath},
                          {"layers", stack.layers.size()},
                          {"thickness_m", r.elastic.thickness},
                          {"E_Pa", r.elastic.youngsModulus},
                          {"nu", r.elastic.poissonRatio},
                          {"yield_Pa", r.firstYieldStress},
                          {"yield_strain", r.firstYieldStrain},
                          {"tangent_modulus_Pa", r.tangentModulus},
                          {"tangent_modulus_from", r.tangentFrom},
                          {"limit_stress_Pa", r.limitStress},
                          {"failure_strain", r.failureStrain},
                          {"peak_stress_Pa", r.peakStress},
                          {"events", events}};
    if (recovery) {
      nlohmann::json totals = nlohmann::json::object();
      for (size_t i = 0; i < recovery->materials.size(); ++i)
        totals[recovery->materials[i].name] = recovery->totalThickness[i];
      doc["recovery"] = {{"total_thickness_m", totals},
                         {"residual_E_relative", recovery->residualModulus},
                         {"residual_nu", recovery->residualPoisson},
                         {"residual_thickness_relative", recovery->residualThickness},
                         {"evaluations", recovery->evaluations},
                         {"algorithm", recovery->algorithm}};
    }
    printJson(doc);
    return;
  }

  std::cout << stack.name << " (" << o.stackPath << "): " << stack.layers.size() << " layers, t = "
            << units::format(r.elastic.thickness, "mm", 5) << "\n";
  if (recovery) {
    std::cout << "Recovered stacking (" << recovery->algorithm << ", " << recovery->evaluations << " evaluations):\n";
    for (size_t i = 0; i < recovery->materials.size(); ++i)
      std::cout << "  " << recovery->materials[i].name << ": " << units::format(recovery->totalThickness[i], "mm", 5)
                << " in total\n";
    std::cout << "  residuals: E/E* - 1 = " << recovery->residualModulus << ", nu - nu* = " << recovery->residualPoisson
              << ", t/t* - 1 = " << recovery->residualThickness << "\n";
    if (!o.writeStackPath.empty()) std::cout << "  written to " << o.writeStackPath << "\n";
  }
  std::cout << "Equivalent material (seed 000 §3.3):\n"
            << "  Young's modulus E            " << units::format(r.elastic.youngsModulus, "MPa", 5) << "\n"
            << "  Poisson's ratio nu           " << std::setprecision(4) << r.elastic.poissonRatio << "\n"
            << "  yield stress (first yield a) " << units::format(r.firstYieldStress, "MPa", 4) << " at strain "
            << r.firstYieldStrain << "\n"
            << "  tangent modulus (line " << (r.tangentFrom.empty() ? "none" : r.tangentFrom.substr(0, 1)) << "-d)   "
            << units::format(r.tangentModulus, "MPa", 4) << "\n"
            << "  limit stress (first ply failure d) " << units::format(r.limitStress, "MPa", 4) << "\n"
            << "  failure strain               " << r.failureStrain << "\n"
            << "  peak stress of the whole curve " << units::format(r.peakStress, "MPa", 4) << "\n"
            << "Kinks (strain, stress before, stress after, event):\n";
  for (const auto& e : r.events)
    std::cout << "  " << std::setw(9) << e.strain << "  " << std::setw(12) << units::format(e.stress, "MPa", 4) << "  "
              << std::setw(12) << units::format(e.stressAfter, "MPa", 4) << "  " << eventKind(e.kind) << " layer "
              << e.layer + 1 << " (" << e.material << ")\n";
  if (!o.curvePath.empty()) std::cout << "Curve written to " << o.curvePath << "\n";
  if (!o.cardPath.empty()) std::cout << "Material card written to " << o.cardPath << "\n";
}

}  // namespace

void registerLaminateCommand(CLI::App& analytic) {
  auto* cmd = analytic.add_subcommand(
      "laminate",
      "Laminate equivalent model of the MLI (seed 000 §3): equivalent E, nu, yield stress, tangent modulus,\n"
      "limit stress and failure strain of a stack of layers under uniaxial in-plane tension, with progressive\n"
      "yield (von Mises) and failure (max principal strain).\n"
      "  blt analytic laminate data/materials/mli_stack.toml --curve mli_curve.csv --card mli_card.toml\n"
      "  blt analytic laminate data/materials/mli_stack.toml --recover --write-stack new_stack.toml\n"
      "The yield stress is the laminate stress at the first layer yield; the tangent modulus is the slope of the\n"
      "line from the second yield point to the first ply failure (seed 000, text after Fig. 9); the limit stress\n"
      "and failure strain are those of the first ply failure.");
  auto o = std::make_shared<LaminateOptions>();
  cmd->add_option("stack", o->stackPath,
                  "Stack file (TOML, [[layer]] tables with material, thickness and Table 2 properties)")
      ->required();
  cmd->add_option("--curve", o->curvePath, "Write the stress-strain curve as CSV (strain,stress_MPa,event)");
  cmd->add_option("--card", o->cardPath,
                  "Write the equivalent material card (library TOML format; density and EOS from the stack's [card])");
  cmd->add_flag("--recover", o->recover,
                "Re-fit each material's total thickness to the targets (NLopt) before the analysis; the stack's "
                "layers give the materials and the layer pattern");
  cmd->add_option("--write-stack", o->writeStackPath, "With --recover: write the recovered stack file here")
      ->needs("--recover");
  addQuantity(*cmd, "--target-E", o->target.youngsModulus, units::pressure,
              "With --recover: target equivalent Young's modulus (default 261.27 MPa, seed 000 Table 4)");
  addQuantity(*cmd, "--target-nu", o->target.poissonRatio, units::dimensionless,
              "With --recover: target equivalent Poisson's ratio (default 0.195, seed 000 Table 4)");
  addQuantity(*cmd, "--target-thickness", o->target.thickness, units::length,
              "With --recover: target total thickness (default 1.0 mm, seed 000 §5)");
  addJsonFlag(*cmd, o->json);
  cmd->callback([o] {
    if (!o->recover && !o->writeStackPath.empty())
      throw InputError(InputLocation::flag("--write-stack"), "only meaningful with --recover", "add --recover");
    if (o->recover) {
      if (!(o->target.youngsModulus > 0))
        throw InputError(InputLocation::flag("--target-E"), "must be positive", "e.g. \"261.27 MPa\"");
      if (!(o->target.poissonRatio > -1 && o->target.poissonRatio < 0.5) || o->target.poissonRatio == 0)
        throw InputError(InputLocation::flag("--target-nu"), "out of range", "-1 < nu < 0.5, nu != 0");
      if (!(o->target.thickness > 0))
        throw InputError(InputLocation::flag("--target-thickness"), "must be positive", "e.g. \"1.0 mm\"");
    }
    run(*o);
  });
}

}  // namespace blt::cli
