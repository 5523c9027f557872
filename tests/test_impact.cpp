// Impact scenarios, the perforation verdict, hole sizes and bisection (issue 5).
#include <doctest/doctest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>

#include "approx.hpp"
#include "blt/ble/nasa.hpp"
#include "blt/sim/impact.hpp"
#include "blt/sim/impact_model.hpp"
#include "run_blt.hpp"

using namespace blt::sim;
namespace fs = std::filesystem;

namespace {

// A 2A12 sphere on one 5A06 plate, coarse: the projectile has 10 particles per diameter.
std::string plateScenario(const std::string& extra = {}) {
  return R"toml(name = "plate"
[projectile]
diameter = "1 mm"
material = "al_2a12"
velocity = "3 km/s"
[target]
lateral_size = "10 mm"
[[target.layer]]
name = "plate"
material = "al_5a06"
thickness = "1 mm"
[resolution]
particle_spacing = "0.1 mm"
[run]
max_time = "5 us"
)toml" + extra;
}

std::string messageOf(const std::function<void()>& f) {
  try {
    f();
  } catch (const blt::InputError& e) {
    return e.what();
  }
  return "";
}

bool contains(const std::string& text, const std::string& part) { return text.find(part) != std::string::npos; }

}  // namespace

TEST_CASE("scenario: every shipped scenario file reads and its materials resolve") {
  int files = 0;
  for (const auto& entry : fs::directory_iterator(std::string(BLT_DATA_DIR) + "/scenarios")) {
    if (entry.path().extension() != ".toml") continue;
    CAPTURE(entry.path().string());
    const ImpactScenario sc = loadScenario(entry.path().string());
    CHECK(!sc.target.layers.empty());
    CHECK(sc.run.maxTime > 0);
    CHECK(resolveMaterial(sc.projectile.material, {}).density > 0);
    for (const auto& l : sc.target.layers) CHECK(resolveMaterial(l.material, {}).density > 0);
    ++files;
  }
  CHECK(files == 9);  // the eight scenarios issue 5 asks for, and the plate of seed 000's target alone
}

TEST_CASE("scenario: settings change any key, layers by number or by name") {
  const std::string dir = std::string(BLT_DATA_DIR) + "/scenarios/";
  // The corrected model of seed 000 sec. 5.3 is the original with 1.75 mm gaps before the MLI and the liner.
  const ImpactScenario original = loadScenario(dir + "fabric_al_original.toml");
  const ImpactScenario corrected = loadScenario(dir + "fabric_al_corrected.toml");
  const ImpactScenario set = loadScenario(dir + "fabric_al_original.toml",
                                          {"target.layer.mli.gap_before=1.75mm", "target.layer.3.gap_before=1.75 mm",
                                           "projectile.diameter=1.4mm", "projectile.angle=45deg", "run.frames=3"});
  REQUIRE(set.target.layers.size() == corrected.target.layers.size());
  for (std::size_t i = 0; i < set.target.layers.size(); ++i)
    CHECK(std::fabs(set.target.layers[i].gapBefore - corrected.target.layers[i].gapBefore) < 1e-12);
  CHECK(original.target.totalDepth() == relApprox(3.0e-3));   // seed 000 sec. 5: 0.4 + 1.0 + 0.2 + 1.4 mm
  CHECK(corrected.target.totalDepth() == relApprox(6.5e-3));  // seed 000 sec. 5.3: the mean specimen thickness
  CHECK(set.projectile.diameter == relApprox(1.4e-3));
  CHECK(set.projectile.angle == relApprox(M_PI / 4));
  CHECK(set.run.frames == 3);
  CHECK(bool(original.resolvedMode() == ModelMode::axisymmetric));
  CHECK(bool(set.resolvedMode() == ModelMode::threeD));
}

TEST_CASE("impact model: a yawed cylinder lies along its tilted axis and flies along the shot line") {
  // Reference: the geometry asked for. A flat cylinder of r = 0.5 mm, L = 3 mm at normal incidence with 30 deg of
  // yaw has its axis at 30 deg from the normal in the x-z plane, moves along -z, and has the cylinder's mass,
  // rho pi r^2 L, halved by the symmetry plane y = 0 (no plane x = 0 now: the body is not symmetric about it).
  const ImpactScenario sc = parseScenario(plateScenario(), "plate.toml",
                                          {"projectile.shape=cylinder", "projectile.length=3mm", "projectile.yaw=30deg"});
  CHECK(std::string(toString(sc.resolvedMode())) == "3d");
  const ImpactModel<3> m = buildImpactModel<3>(sc, 1);
  CHECK_FALSE(m.mirrorX);
  const double r = 0.5e-3, L = 3e-3;
  CHECK(m.projectileMass == relApprox(2770 * M_PI * r * r * L / 2, 1e-6));
  const auto& P = m.solver->particles();
  // The axis from the covariance of the particles' x and z (the y extent, 0 to r, is far shorter than L).
  double n = 0, mx = 0, mz = 0;
  for (std::size_t p = 0; p < P.size(); ++p)
    if (P.body[p] == 0) n += 1, mx += P.position[p][0], mz += P.position[p][2];
  mx /= n, mz /= n;
  double sxx = 0, szz = 0, sxz = 0;
  for (std::size_t p = 0; p < P.size(); ++p)
    if (P.body[p] == 0) {
      const double dx = P.position[p][0] - mx, dz = P.position[p][2] - mz;
      sxx += dx * dx, szz += dz * dz, sxz += dx * dz;
      CHECK(P.velocity[p][0] == 0.0);
      CHECK(P.velocity[p][2] == relApprox(-3000.0, 1e-12));
    }
  // Principal direction of [[sxx, sxz], [sxz, szz]]: angle phi from the z axis with tan(2 phi) = 2 sxz / (szz - sxx);
  // the axis goes towards +x as it goes towards -z, so sxz < 0.
  const double tilt = 0.5 * std::atan2(-2 * sxz, szz - sxx);
  CHECK(tilt * 180 / M_PI == doctest::Approx(30.0).epsilon(0.02));
  // The shot line through the centre of mass still meets the front face at the origin, along the normal.
  CHECK(std::fabs(m.shotLineAt(0.0)[0]) < 1e-12);
  CHECK(m.direction[2] == -1.0);
  // Spheres have no yaw; a yawed body has no axisymmetric model.
  CHECK(contains(messageOf([] { parseScenario(plateScenario(), "plate.toml", {"projectile.yaw=5deg"}); }),
                 "a sphere has no axis to yaw"));
  CHECK(contains(messageOf([] {
                   parseScenario(plateScenario(), "plate.toml",
                                 {"projectile.shape=cylinder", "projectile.length=3mm", "projectile.yaw=5deg",
                                  "run.mode=axisymmetric"});
                 }),
                 "yawed projectile cannot run axisymmetric"));
  CHECK(contains(messageOf([] {
                   parseScenario(plateScenario(), "plate.toml",
                                 {"projectile.shape=cylinder", "projectile.length=3mm", "projectile.angle=60deg",
                                  "projectile.yaw=30deg"});
                 }),
                 "projectile.yaw"));
}

TEST_CASE("impact model: an off-centre aim moves the shot line's meeting with the front face and nothing else") {
  // Reference: the definition of projectile.aim_offset. The line through the projectile's centre of mass along its
  // velocity (sin 45, 0, -cos 45) meets z = 0 at x = cx + cz tan 45: the offset asked for (0 by default).
  std::size_t centred = 0;  // target points of the centred shot
  for (const double aim : {0.0, -2e-3, 1.5e-3}) {
    CAPTURE(aim);
    const ImpactScenario sc = parseScenario(plateScenario(), "plate.toml",
                                            {"projectile.angle=45deg", "projectile.aim_offset=" + std::to_string(aim * 1e3) + "mm"});
    const ImpactModel<3> m = buildImpactModel<3>(sc, 1);
    const auto& P = m.solver->particles();
    double mass = 0, cx = 0, cz = 0;
    std::size_t targetPoints = 0;
    for (std::size_t p = 0; p < P.size(); ++p) {
      if (P.body[p] != 0) {
        ++targetPoints;
        continue;
      }
      mass += P.mass[p], cx += P.mass[p] * P.position[p][0], cz += P.mass[p] * P.position[p][2];
    }
    cx /= mass, cz /= mass;
    CHECK(cx + cz * std::tan(M_PI / 4) == doctest::Approx(aim).epsilon(1e-9).scale(1e-3));
    CHECK(m.shotLineAt(0.0)[0] == doctest::Approx(aim).epsilon(1e-9).scale(1e-3));
    if (aim == 0.0) centred = targetPoints;
    CHECK(targetPoints == centred);  // the target is where it was
  }
  // A normal impact is modelled about its axis; the line must meet the target.
  CHECK(contains(messageOf([] { parseScenario(plateScenario(), "plate.toml", {"projectile.aim_offset=1mm"}); }),
                 "projectile.aim_offset"));
  CHECK(contains(messageOf([] {
                   parseScenario(plateScenario(), "plate.toml", {"projectile.angle=30deg", "projectile.aim_offset=-5mm"});
                 }),
                 "off the target"));
}

TEST_CASE("impact model: a grid offset moves the nodes along the normal and leaves the bodies where they are") {
  // Reference: the definition of resolution.grid_offset, f of a cell: node 0 lies f h further back, every
  // particle of the model has the same position, volume and mass.
  const ImpactScenario plain = parseScenario(plateScenario(), "plate.toml");
  const ImpactScenario shifted = parseScenario(plateScenario(), "plate.toml", {"resolution.grid_offset=0.5"});
  const ImpactModel<2> a = buildImpactModel<2>(plain, 1), b = buildImpactModel<2>(shifted, 1);
  const double h = plain.cellSize();
  CHECK(b.solver->grid().lower[1] == relApprox(a.solver->grid().lower[1] - 0.5 * h, 1e-12));
  CHECK(b.solver->grid().lower[0] == a.solver->grid().lower[0]);  // the axis stays a node line
  const auto &pa = a.solver->particles(), &pb = b.solver->particles();
  REQUIRE(pa.size() == pb.size());
  for (std::size_t p = 0; p < pa.size(); ++p) {
    CHECK(pb.position[p][0] == pa.position[p][0]);
    CHECK(pb.position[p][1] == pa.position[p][1]);
    CHECK(pb.mass[p] == pa.mass[p]);
  }
  CHECK(contains(messageOf([] { parseScenario(plateScenario(), "plate.toml", {"resolution.grid_offset=1"}); }),
                 "fraction of a cell"));
}

TEST_CASE("scenario: solver.contact_strain reads per-node (the default) and per-particle, and nothing else, and per-particle only where it acts") {
  CHECK(parseScenario(plateScenario(), "plate.toml").solver.contact.strain == ContactStrain::perNode);
  CHECK(parseScenario(plateScenario(), "plate.toml", {"solver.contact_strain=per-particle"}).solver.contact.strain ==
        ContactStrain::perParticle);
  const std::string bad =
      messageOf([] { parseScenario(plateScenario(), "plate.toml", {"solver.contact_strain=per-cell"}); });
  CHECK(contains(bad, "contact_strain"));
  CHECK(contains(bad, "per-particle"));
  // Where it would change nothing it is refused, naming the key that makes it so.
  const std::string usl = messageOf([] {
    parseScenario(plateScenario(), "plate.toml", {"solver.contact_strain=per-particle", "solver.scheme=usl"});
  });
  CHECK(contains(usl, "contact_strain"));
  CHECK(contains(usl, "scheme = usl"));
  const std::string single = messageOf([] {
    parseScenario(plateScenario(), "plate.toml", {"solver.contact_strain=per-particle", "solver.contact=single-field"});
  });
  CHECK(contains(single, "contact = single-field"));
  CHECK_NOTHROW(parseScenario(plateScenario(), "plate.toml", {"solver.contact_strain=per-node", "solver.scheme=usl"}));
}

TEST_CASE("scenario: a bad key or value is an error naming the file, line or flag, and the key") {
  const std::string unknownKey = messageOf([] { parseScenario(plateScenario("frame = 3\n"), "plate.toml"); });
  CHECK(contains(unknownKey, "plate.toml"));
  CHECK(contains(unknownKey, "frame"));
  CHECK(contains(unknownKey, "unknown key"));
  const std::string viaFlag = messageOf([] { parseScenario(plateScenario(), "plate.toml", {"projectile.diamter=1mm"}); });
  CHECK(contains(viaFlag, "--set"));
  CHECK(contains(viaFlag, "projectile.diamter"));
  const std::string noUnit = messageOf([] { parseScenario(plateScenario(), "plate.toml", {"projectile.velocity=3000"}); });
  CHECK(contains(noUnit, "projectile.velocity"));
  CHECK(contains(noUnit, "unit"));
  const std::string badLayer = messageOf([] { parseScenario(plateScenario(), "plate.toml", {"target.layer.5.thickness=1mm"}); });
  CHECK(contains(badLayer, "no layer '5'"));
  const std::string oblique = messageOf(
      [] { parseScenario(plateScenario(), "plate.toml", {"projectile.angle=30deg", "run.mode=axisymmetric"}); });
  CHECK(contains(oblique, "oblique"));
  const std::string material = messageOf([] {
    const ImpactScenario sc = parseScenario(plateScenario(), "plate.toml", {"projectile.material=unobtainium"});
    buildImpactModel<2>(sc, 1);
  });
  CHECK(contains(material, "unobtainium"));
  CHECK(contains(material, "projectile.material"));
  const std::string tooNarrow = messageOf([] {
    const ImpactScenario sc = parseScenario(plateScenario(), "plate.toml",
                                            {"projectile.shape=cylinder", "projectile.length=20mm",
                                             "projectile.angle=60deg", "resolution.particle_spacing=0.25mm"});
    buildImpactModel<3>(sc, 1);
  });
  CHECK(contains(tooNarrow, "target.lateral_size"));
}

TEST_CASE("impact model: the projectile has the exact mass of its solid and starts one cell in front") {
  // Reference: the volumes of a sphere (4/3 pi r^3), a cylinder with a hemispherical nose
  // (pi r^2 (L - r) + 2/3 pi r^3) and with a conical nose (pi r^2 (L - Ln) + pi r^2 Ln / 3).
  const double rho = 2770;  // al_2a12
  {
    const ImpactScenario sc = parseScenario(plateScenario(), "plate.toml");
    const ImpactModel<2> m = buildImpactModel<2>(sc, 1);
    const double r = 0.5e-3;
    CHECK(m.projectileMass == relApprox(rho * 4.0 / 3.0 * M_PI * r * r * r / (2 * M_PI), 1e-12));
    double lowest = 1;
    const auto& P = m.solver->particles();
    for (std::size_t p = 0; p < P.size(); ++p)
      if (P.body[p] == 0) lowest = std::min(lowest, P.position[p][1] - P.halfSize[p][1]);
    CHECK(lowest == relApprox(sc.cellSize(), 1e-9));
    REQUIRE(m.layers.size() == 1);
    CHECK(m.layers[0].front == 0.0);
    CHECK(m.layers[0].rear == relApprox(-1e-3));
  }
  for (const std::string nose : {"hemispherical", "conical"}) {
    CAPTURE(nose);
    std::vector<std::string> settings = {"projectile.shape=cylinder", "projectile.length=3mm",
                                         "projectile.nose=" + nose, "projectile.angle=30deg"};
    if (nose == "conical") settings.push_back("projectile.nose_length=1mm");
    const ImpactScenario sc = parseScenario(plateScenario(), "plate.toml", settings);
    const ImpactModel<3> m = buildImpactModel<3>(sc, 1);
    const double r = 0.5e-3, L = 3e-3;
    const double volume = nose == "hemispherical" ? M_PI * r * r * (L - r) + 2.0 / 3.0 * M_PI * r * r * r
                                                  : M_PI * r * r * (L - 1e-3) + M_PI * r * r * 1e-3 / 3.0;
    CHECK(m.projectileMass == relApprox(rho * volume / 2, 1e-6));  // half model
    // The shot line through the centre of mass meets the front face at the origin.
    CHECK(std::fabs(m.shotLineAt(0.0)[0]) < 1e-12);
    CHECK(m.direction[0] == relApprox(0.5));
  }
}

TEST_CASE("verdict: an intact target is not perforated and has no holes") {
  const ImpactScenario sc = parseScenario(plateScenario(), "plate.toml");
  const ImpactModel<2> m = buildImpactModel<2>(sc, 1);
  const PerforationVerdict v = assessPerforation<2>(m, sc.verdict, {1.0, 1.0}, true);
  CHECK_FALSE(v.perforated);
  CHECK_FALSE(v.rearOpening);
  CHECK(v.massBehind == 0.0);
  REQUIRE(v.holes.size() == 1);
  CHECK(v.holes[0].horizontal == 0.0);
}

TEST_CASE("verdict: a hole cut into the rear wall is measured and is an opening") {
  // Reference: the geometry cut by hand. Axisymmetric: a 1.2 mm diameter hole; 3D half model at 30 deg (the shot
  // line crosses the plate's mid-plane at x = 0.5 mm tan 30 deg): a 2.0 mm x 1.2 mm rectangle about it.
  {
    const ImpactScenario sc = parseScenario(plateScenario(), "plate.toml");
    ImpactModel<2> m = buildImpactModel<2>(sc, 1);
    auto& P = m.solver->particles();
    for (std::size_t p = 0; p < P.size(); ++p)
      if (P.body[p] == 1 && P.position[p][0] < 0.6e-3) P.active[p] = 0;
    const PerforationVerdict v = assessPerforation<2>(m, sc.verdict, {1.0, 1.0}, true);
    CHECK(v.rearOpening);
    CHECK(v.perforated);
    CHECK(v.holes[0].horizontal == relApprox(1.2e-3, 1e-6));
    CHECK(v.holes[0].vertical == relApprox(1.2e-3, 1e-6));
    // The projectile, still in front of the wall, is its residual velocity while it flies on into the hole, and
    // has none once it is thrown back out (as seed 003's T4 threw its projectile back out of an opened wall).
    for (std::size_t p = 0; p < P.size(); ++p)
      if (P.body[p] == 0) P.velocity[p] = Vec<2>(0.0, -30.0);
    const PerforationVerdict into = assessPerforation<2>(m, sc.verdict, {1.0, 1.0}, false);
    CHECK(into.perforated);
    CHECK(into.residualVelocity == relApprox(30.0, 1e-12));
    CHECK(into.residualFrom == "projectile");
    for (std::size_t p = 0; p < P.size(); ++p)
      if (P.body[p] == 0) P.velocity[p] = Vec<2>(0.0, 30.0);
    const PerforationVerdict back = assessPerforation<2>(m, sc.verdict, {1.0, 1.0}, false);
    CHECK(back.perforated);
    CHECK(back.residualVelocity == 0.0);
    CHECK(back.residualFragmentMass == 0.0);
    CHECK(back.residualFrom.empty());
  }
  {
    const ImpactScenario sc = parseScenario(plateScenario(), "plate.toml", {"projectile.angle=30deg",
                                                                            "resolution.particle_spacing=0.2mm"});
    ImpactModel<3> m = buildImpactModel<3>(sc, 1);
    const double xc = m.shotLineAt(-0.5e-3)[0];
    CHECK(xc == relApprox(0.5e-3 * std::tan(M_PI / 6), 1e-9));
    auto& P = m.solver->particles();
    // Whole particles: the 0.2 mm lattice has particle centres at odd multiples of 0.1 mm.
    const double x0 = 0.2e-3 * std::round(xc / 0.2e-3);
    for (std::size_t p = 0; p < P.size(); ++p)
      if (P.body[p] == 1 && std::fabs(P.position[p][0] - x0) < 1.0e-3 && P.position[p][1] < 0.6e-3) P.active[p] = 0;
    const PerforationVerdict v = assessPerforation<3>(m, sc.verdict, {1.0, 1.0}, true);
    CHECK(v.rearOpening);
    CHECK(v.holes[0].horizontal == relApprox(2.0e-3, 1e-6));
    CHECK(v.holes[0].vertical == relApprox(1.2e-3, 1e-6));
  }
}

TEST_CASE("verdict: a whole plate whose domains cross the symmetry plane has no opening along it") {
  // Reference: the plate is whole, so nothing may be open. Seen in 45 deg runs of the seed 000 target: domains
  // next to y = 0 stretched across it put the first voxel row mostly outside the model, and that empty row read
  // as a through-thickness opening on the shot line (a false perforation 25 us after impact).
  const ImpactScenario sc = parseScenario(plateScenario(), "plate.toml", {"projectile.angle=30deg",
                                                                          "resolution.particle_spacing=0.2mm"});
  ImpactModel<3> m = buildImpactModel<3>(sc, 1);
  auto& P = m.solver->particles();
  const double x0 = m.shotLineAt(-0.5e-3)[0];
  for (std::size_t p = 0; p < P.size(); ++p)
    if (P.body[p] == 1 && P.position[p][1] < 0.2e-3 && std::fabs(P.position[p][0] - x0) < 0.3e-3)
      P.deformationGradient[p](1, 1) = 4.0;  // reaches 0.3 mm below y = 0, more than a voxel
  CHECK_FALSE(assessPerforation<3>(m, sc.verdict, {1.0, 1.0}, true).rearOpening);
}

TEST_CASE("verdict: debris sliding along the plate does not keep a run unsettled, debris moving rearward does") {
  // Reference: the definition in verdict.hpp, on states set by hand. The projectile's points move along the plate
  // (x) at 3 km/s: all the kinetic energy is there, none of it rearward, so the stop is settled. Turned towards
  // the rear at the same speed, its rearward kinetic energy equals the initial one: not settled.
  const ImpactScenario sc = parseScenario(plateScenario(), "plate.toml", {"projectile.angle=30deg"});
  ImpactModel<3> m = buildImpactModel<3>(sc, 1);
  const KineticReference initial = kineticReference<3>(m);
  REQUIRE(initial.rearward == relApprox(initial.total * 0.75, 1e-9));  // cos^2 30 deg
  auto& P = m.solver->particles();
  for (std::size_t p = 0; p < P.size(); ++p)
    if (P.body[p] == 0) P.velocity[p] = Vec<3>(3000.0, 0.0, 0.0);
  const PerforationVerdict sliding = assessPerforation<3>(m, sc.verdict, initial, false);
  CHECK(sliding.settled);
  CHECK_FALSE(sliding.perforated);
  CHECK(sliding.rearwardKineticFraction == 0.0);
  for (std::size_t p = 0; p < P.size(); ++p)
    if (P.body[p] == 0) P.velocity[p] = Vec<3>(0.0, 0.0, -3000.0);
  const PerforationVerdict rearward = assessPerforation<3>(m, sc.verdict, initial, false);
  CHECK_FALSE(rearward.settled);
  CHECK(rearward.rearwardKineticFraction == relApprox(3000.0 * 3000.0 / (sc.projectile.velocity * sc.projectile.velocity * 0.75), 1e-9));
}

TEST_CASE("verdict: a ring of failed material around a hole counts in the hole, not in the opening") {
  // Reference: the geometry cut by hand: no material inside r = 0.6 mm, failed material out to r = 1.0 mm.
  const ImpactScenario sc = parseScenario(plateScenario(), "plate.toml");
  ImpactModel<2> m = buildImpactModel<2>(sc, 1);
  auto& P = m.solver->particles();
  for (std::size_t p = 0; p < P.size(); ++p) {
    if (P.body[p] != 1) continue;
    if (P.position[p][0] < 0.6e-3) P.active[p] = 0;
    else if (P.position[p][0] < 1.0e-3) P.failed[p] = 1;
  }
  const PerforationVerdict v = assessPerforation<2>(m, sc.verdict, {1.0, 1.0}, true);
  CHECK(v.holes[0].horizontal == relApprox(2.0e-3, 1e-6));
  CHECK(v.holes[0].openingHorizontal == relApprox(1.2e-3, 1e-6));
  CHECK(v.holes[0].openingVertical == relApprox(1.2e-3, 1e-6));
}

TEST_CASE("verdict: material separated behind the rear wall perforates it and gives the residual velocity") {
  const ImpactScenario sc = parseScenario(plateScenario(), "plate.toml");
  ImpactModel<2> m = buildImpactModel<2>(sc, 1);
  auto& P = m.solver->particles();
  // The projectile moved to 1 mm behind the plate, flying on at 1234 m/s; the plate is whole.
  for (std::size_t p = 0; p < P.size(); ++p)
    if (P.body[p] == 0) {
      P.position[p][1] -= 3.5e-3;
      P.velocity[p] = Vec<2>(0.0, -1234.0);
    }
  const PerforationVerdict v = assessPerforation<2>(m, sc.verdict, {1.0, 1.0}, false);
  CHECK(v.perforated);
  CHECK(v.settled);
  CHECK(v.massBehindFraction == relApprox(1.0, 1e-12));
  CHECK(v.residualVelocity == relApprox(1234.0, 1e-12));
  CHECK(v.residualFragmentMass == relApprox(m.projectileMass * 2 * M_PI, 1e-12));
  CHECK(v.residualFrom == "projectile");
  // Moving back towards the wall it is not counted.
  for (std::size_t p = 0; p < P.size(); ++p)
    if (P.body[p] == 0) P.velocity[p] = Vec<2>(0.0, 100.0);
  CHECK_FALSE(assessPerforation<2>(m, sc.verdict, {1.0, 1.0}, false).perforated);
  // Gone out through the grid's rear face (the solver freezes such points, inactive), it still gives the residual
  // velocity, as it left.
  const double floor = m.solver->grid().lower[1];
  for (std::size_t p = 0; p < P.size(); ++p)
    if (P.body[p] == 0) {
      P.position[p][1] = floor - 1e-4;
      P.velocity[p] = Vec<2>(0.0, -500.0);
      P.active[p] = 0;
    }
  const PerforationVerdict gone = assessPerforation<2>(m, sc.verdict, {1.0, 1.0}, false);
  CHECK(gone.perforated);
  CHECK(gone.residualVelocity == relApprox(500.0, 1e-12));
  CHECK(gone.residualFrom == "projectile");
  CHECK(gone.residualFragmentMass == relApprox(m.projectileMass * 2 * M_PI, 1e-12));
}

TEST_CASE("verdict: a run stops on a verdict only once it has held over the last half of the time run, and ends on it only then") {
  // The checks of seed 003's T4 at 161.875 m/s as its verdict history shows them (every 10 us from 225 us): the
  // rear wall opened at 305 us and closed again at 355 us, when the rearward kinetic energy was already low.
  const auto verdict = [](bool perforated, bool settled) {
    PerforationVerdict v;
    v.perforated = v.rearOpening = perforated;
    v.settled = settled;
    return v;
  };
  const std::vector<double> spacing{0.25e-3};
  std::vector<VerdictCheck> checks;
  for (int t = 225; t <= 345; t += 10) checks.push_back({t * 1e-6, verdict(t >= 305, false)});
  const PerforationVerdict closed = verdict(false, true);
  CHECK_FALSE(verdictHeld(checks, closed, 355e-6, spacing));  // open 10 us earlier
  // Closed from 355 us on: it holds once the last opening (345 us) is more than half the elapsed time ago.
  for (int t = 355; t <= 685; t += 10) checks.push_back({t * 1e-6, closed});
  CHECK_FALSE(verdictHeld(checks, closed, 685e-6, spacing));  // the window reaches back to 342.5 us
  CHECK(verdictHeld(checks, closed, 695e-6, spacing));         // back to 347.5 us: closed throughout
  CHECK_FALSE(verdictHeld(checks, verdict(false, false), 695e-6, spacing));  // and it must be settled
  // A run that never opened stops as soon as it is settled.
  const std::vector<VerdictCheck> neverOpen{{100e-6, verdict(false, false)}, {200e-6, verdict(false, false)}};
  CHECK(verdictHeld(neverOpen, closed, 210e-6, spacing));
  CHECK_FALSE(perforatedLately(neverOpen, 210e-6));
  // One that reaches its end time with the wall closed at the last check only is perforated: seed 003's T2T2 at
  // 164.69 m/s, open from 275 us to 995 us of 1 ms. Open only before the last half, it is not.
  std::vector<VerdictCheck> lateClose;
  for (int t = 5; t <= 995; t += 5) lateClose.push_back({t * 1e-6, verdict(t >= 275, false)});
  CHECK(perforatedLately(lateClose, 1000e-6));
  std::vector<VerdictCheck> earlyClose;
  for (int t = 5; t <= 995; t += 5) earlyClose.push_back({t * 1e-6, verdict(t >= 275 && t < 495, false)});
  CHECK_FALSE(perforatedLately(earlyClose, 1000e-6));

  // A perforation holds once the mass behind, the residual velocity and the holes are those of the latest check
  // at least half the elapsed time ago, which was perforated too.
  PerforationVerdict through = verdict(true, true);
  through.massBehindFraction = 1.0;
  through.residualVelocity = 50.0;
  through.holes = {LayerHole{"plate", 7.0e-3, 7.0e-3}};
  std::vector<VerdictCheck> open{{100e-6, verdict(false, false)}, {200e-6, through}, {390e-6, through}};
  CHECK(verdictHeld(open, through, 400e-6, spacing));
  CHECK_FALSE(verdictHeld(open, through, 390e-6, spacing));  // the check at or before 195 us was not perforated
  PerforationVerdict grown = through;
  grown.holes[0].horizontal += 0.2e-3;  // more than half the plate's particle spacing
  CHECK_FALSE(verdictHeld(open, grown, 400e-6, spacing));
  grown = through;
  grown.residualVelocity = 52.0;  // 4 %
  CHECK_FALSE(verdictHeld(open, grown, 400e-6, spacing));
  grown = through;
  grown.massBehindFraction += 0.01;
  CHECK_FALSE(verdictHeld(open, grown, 400e-6, spacing));
}

TEST_CASE("impact: a single-wall shot on either side of the Cour-Palais limit gets the BLE's verdict") {
  // Independent reference: the NASA single-wall BLE (Cour-Palais; REFERENCE sec. 2), with a Brinell hardness of
  // 70 ASSUMED for 5A06 (the card gives none; d_c scales with BHN^0.24 only). At 3 km/s its critical diameter for
  // 1 mm of 5A06 is well below 1 mm and for 4 mm well above it, so a 1 mm sphere must perforate the first and not
  // the second. Coarse (10 particles per projectile diameter), a few seconds.
  blt::ble::SingleWallTarget thin{1e-3, 2670, 70, 5328}, thick{4e-3, 2670, 70, 5328};
  REQUIRE(blt::ble::singleWallCriticalDiameter(thin, 2770, 3000, 0) < 0.7e-3);
  REQUIRE(blt::ble::singleWallCriticalDiameter(thick, 2770, 3000, 0) > 1.4e-3);
  const ImpactResult through = runImpact(parseScenario(plateScenario(), "plate.toml"), {"", 1, {}});
  CHECK(through.verdict.perforated);
  CHECK(through.verdict.settled);
  CHECK(through.verdict.residualVelocity > 0);
  CHECK(through.verdict.residualVelocity < 3000);
  CHECK(through.verdict.holes.at(0).horizontal > 1e-3);  // a hole wider than the projectile
  CHECK(through.summary["perforated"] == true);
  const ImpactResult stopped =
      runImpact(parseScenario(plateScenario(), "plate.toml", {"target.layer.1.thickness=4mm", "run.max_time=4us"}),
                {"", 1, {}});
  CHECK(std::string(toString(stopped.status)) != "unstable");
  CHECK_FALSE(stopped.verdict.perforated);
  CHECK(stopped.verdict.holes.at(0).horizontal == 0.0);
}

TEST_CASE("impact: seed 000's plate alone has the single-wall BLE's critical diameter at 3 km/s" *
          doctest::test_suite("verification")) {
  // Independent reference: the NASA single-wall BLE (Cour-Palais; REFERENCE sec. 2) for 1.4 mm of 5A06 struck by
  // a 2A12 sphere at 3 km/s, normal: 0.716 mm (Brinell hardness 70 ASSUMED, as above; the target's sound speed
  // from the card). The shipped scenario at its own resolution (seed 000's 0.1 mm, axisymmetric), bisected to
  // +-0.02 mm; within 15 %, the tolerance issue 5 sets for critical diameters. It gave 0.703 mm, (0.688, 0.719],
  // when written (-1.8 %); at 6 km/s 0.483 or 0.503 mm, by the starting bracket, against the BLE's 0.462.
  const ImpactScenario sc =
      loadScenario(std::string(BLT_DATA_DIR) + "/scenarios/fabric_al_plate_only.toml", {"projectile.velocity=3km/s"});
  const blt::Material target = resolveMaterial(sc.target.layers.at(0).material, {});
  const blt::ble::SingleWallTarget plate{sc.target.layers.at(0).thickness, target.density, 70,
                                         target.param("eos", "c0")};
  const double reference =
      blt::ble::singleWallCriticalDiameter(plate, resolveMaterial(sc.projectile.material, {}).density, 3000, 0);
  CHECK(reference == relApprox(0.716e-3, 1e-3));
  BisectionOptions o;
  o.lower = 0.5e-3;
  o.upper = 1.0e-3;
  o.tolerance = 0.02e-3;
  const BisectionResult b = bisectScenario(sc, o, {"", 1, {}});
  REQUIRE(b.resolved);
  CHECK(b.estimate() == relApprox(reference, 0.15));
}

TEST_CASE("bisection: brackets a monotone threshold in log2(width / tolerance) runs and keeps every run") {
  // Reference: a synthetic outcome that perforates above 1.0345 mm.
  const double threshold = 1.0345e-3;
  const auto outcome = [&](double d) {
    BisectionRun r;
    r.perforated = d > threshold;
    return r;
  };
  BisectionOptions o;
  o.lower = 0.8e-3;
  o.upper = 1.4e-3;
  o.tolerance = 0.02e-3;  // +-0.02 mm: the seed's bracket pairs are 0.04 mm apart
  std::vector<double> seen;
  const BisectionResult b = bisect(o, outcome, [&](const BisectionRun& r) { seen.push_back(r.value); });
  CHECK(b.resolved);
  CHECK(b.largestSafe <= threshold);
  CHECK(b.smallestPerforating > threshold);
  CHECK(0.5 * (b.smallestPerforating - b.largestSafe) <= o.tolerance);
  // 0.6 mm halved to 0.0375 mm: four bisections after the two bracket runs (issue 5: at most 6 from a good bracket).
  CHECK(b.runs.size() == 6);
  CHECK(seen.size() == b.runs.size());
  // The run that set the lower end is kept, to tell whether it settled; a trusted lower end has none.
  REQUIRE(b.largestSafeRun() != nullptr);
  CHECK(b.largestSafeRun()->value == b.largestSafe);
  CHECK_FALSE(b.largestSafeRun()->perforated);
  o.checkBracket = false;
  CHECK(bisect(o, outcome).runs.size() == 4);
  const auto alwaysPerforated = [](double) {
    BisectionRun r;
    r.perforated = true;
    return r;
  };
  CHECK(bisect(o, alwaysPerforated).largestSafeRun() == nullptr);

  // A bracket that does not hold says so and keeps what it ran.
  o.checkBracket = true;
  o.upper = 1.0e-3;
  const BisectionResult bad = bisect(o, outcome);
  CHECK_FALSE(bad.resolved);
  CHECK(contains(bad.message, "bracket does not hold"));
  CHECK(bad.runs.size() == 2);
  CHECK(bad.largestSafe == relApprox(1.0e-3));

  // An unstable run ends the bisection with its reason.
  o.upper = 1.4e-3;
  const BisectionResult unstable = bisect(o, [&](double d) {
    BisectionRun r = outcome(d);
    if (d > 1.05e-3 && d < 1.2e-3) r.status = RunStatus::unstable;
    return r;
  });
  CHECK_FALSE(unstable.resolved);
  CHECK(contains(unstable.message, "unstable"));
}

TEST_CASE("blt sim run and blt sim bisect from the command line") {
  const std::string scenario = std::string(BLT_DATA_DIR) + "/scenarios/fabric_al_corrected.toml";
  const BltRun bad = runBlt("sim run '" + scenario + "' --set projectile.colour=red");
  CHECK(bad.status != 0);
  CHECK(contains(bad.output, "projectile.colour"));
  CHECK(contains(bad.output, "--set"));

  const fs::path file = fs::temp_directory_path() / ("blt_test_plate_" + std::to_string(::getpid()) + ".toml");
  {
    std::ofstream out(file);
    out << plateScenario();
  }
  const BltRun r = runBlt("sim run '" + file.string() + "' --json --threads 1");
  REQUIRE(r.status == 0);
  const auto doc = nlohmann::json::parse(r.output.substr(r.output.find('{')));
  CHECK(doc["perforated"] == true);
  CHECK(doc.contains("residual_velocity_m_s"));
  CHECK(doc["hole_size_mm"].size() == 1);
  CHECK(doc["hole_size_mm"][0].size() == 2);
  CHECK(doc.contains("wall_time_s"));

  const BltRun b = runBlt("sim bisect '" + file.string() +
                          "' --on diameter --lo 0.3mm --hi 1mm --tol 0.1mm --trust-bracket --json --threads 1");
  REQUIRE(b.status == 0);
  const auto bis = nlohmann::json::parse(b.output.substr(b.output.find('{')));
  CHECK(bis["runs"].size() == bis["run_count"]);
  CHECK(bis.contains("largest_not_perforating_mm"));
  CHECK(bis.contains("largest_not_perforating_settled"));
  CHECK(contains(b.output, "  run diameter = "));  // progress, one line per run on stderr, with --json too
  // and a closing line there, as the result goes to stdout only
  CHECK(contains(b.output, bis["resolved"].get<bool>() ? "bisection resolved: ballistic limit " : "bisection not resolved"));

  // An ensemble over grid offsets: one run per offset, and the count is of those runs' own verdicts.
  const BltRun e = runBlt("sim run '" + file.string() + "' --ensemble 2 --json --threads 1");
  REQUIRE(e.status == 0);
  const auto ens = nlohmann::json::parse(e.output.substr(e.output.find('{')));
  REQUIRE(ens["runs"].size() == 2);
  CHECK(ens["grid_offsets"] == nlohmann::json::array({0.0, 0.5}));
  int perforated = 0;
  for (const auto& run : ens["runs"]) perforated += run["perforated"].get<bool>();
  CHECK(ens["perforated_count"] == perforated);
  CHECK(ens["perforated_fraction"].get<double>() == doctest::Approx(perforated / 2.0));
  CHECK(contains(runBlt("sim run '" + file.string() + "' --ensemble 0").output, "--ensemble"));
  fs::remove(file);
}

namespace {
std::string readText(const fs::path& p) {
  std::ifstream in(p);
  return std::string(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
}

// The frame times a .pvd lists, in order.
std::vector<std::string> pvdTimes(const fs::path& p) {
  std::vector<std::string> times;
  const std::string text = readText(p);
  for (std::size_t at = text.find("timestep=\""); at != std::string::npos; at = text.find("timestep=\"", at + 1))
    times.push_back(text.substr(at + 10, text.find('"', at + 10) - at - 10));
  return times;
}
}  // namespace

TEST_CASE("impact: eroded points kept as mass carry their momentum on, and removed ones take it out of the model") {
  // Independent check: with free faces and no boundary forces, MPM conserves the axial momentum sum m v_z to
  // round-off (the nodal internal forces sum to zero by the shape functions' partition of unity, and P2G and G2P
  // pass momentum on whole). Seed 000's fabric target, axisymmetric and coarse, case 05 of Table 1 (1.2 mm,
  // 4.03 km/s) for 10 us: the sound-speed erosion takes out some fabric and MLI points.
  const std::string path = std::string(BLT_DATA_DIR) + "/scenarios/fabric_al_corrected.toml";
  for (const bool keep : {false, true}) {
    CAPTURE(keep);
    const ImpactScenario sc =
        loadScenario(path, {"resolution.particle_spacing=0.2mm", "resolution.cell_size=0.2mm", "target.edge=free",
                            std::string("solver.keep_eroded_mass=") + (keep ? "true" : "false")});
    ImpactModel<2> m = buildImpactModel<2>(sc, 1);
    const Particles<2>& P = m.solver->particles();
    const auto axialMomentum = [&](bool active) {
      double sum = 0;
      for (std::size_t p = 0; p < P.size(); ++p)
        if ((P.active[p] != 0) == active) sum += P.mass[p] * P.velocity[p][1];
      return sum;
    };
    const double initial = axialMomentum(true);
    REQUIRE(initial < 0);  // the projectile flies towards -z
    while (m.solver->time() < 10e-6) m.solver->step();
    // Points also go when they leave the grid (spray off the front face); the others that went were eroded.
    const GridSpec<2>& g = m.solver->grid();
    const auto offGrid = [&](std::size_t p) {
      for (int a = 0; a < 2; ++a)
        if (P.position[p][a] < g.lower[a] - 0.5 * g.cellSize || P.position[p][a] > g.upper[a] + 0.5 * g.cellSize) return true;
      return false;
    };
    std::size_t kept = 0, removedInside = 0;
    double momentumOffGrid = 0;
    for (std::size_t p = 0; p < P.size(); ++p) {
      if (!P.active[p] && offGrid(p)) momentumOffGrid += P.mass[p] * P.velocity[p][1];
      if (!P.active[p] && !offGrid(p)) ++removedInside;
      if (P.active[p] && P.failed[p] == kEroded) {
        ++kept;
        CHECK(P.stress[p].norm() == 0.0);
      }
    }
    // A removed point keeps its last velocity: what the model lost is exactly what the removed points carry.
    CHECK(axialMomentum(true) + axialMomentum(false) == doctest::Approx(initial).epsilon(1e-9));
    if (keep) {
      CHECK(kept > 0);
      CHECK(removedInside == 0);
      // What the model holds is the initial momentum less what flew off the grid.
      CHECK(axialMomentum(true) + momentumOffGrid == doctest::Approx(initial).epsilon(1e-9));
    } else {
      CHECK(kept == 0);
      CHECK(removedInside > 0);
      CHECK(std::abs(axialMomentum(true) + momentumOffGrid - initial) > 1e-4 * std::abs(initial));
    }
    // The run's summary accounts for the same points, per body.
    ImpactScenario ten = sc;
    ten.run.maxTime = 10e-6;
    ten.run.stopWhenSettled = false;
    const ImpactResult r = runImpact(ten, {"", 1, {}});
    const auto& bodies = r.summary.at("removed");
    REQUIRE(bodies.size() == 5);
    CHECK(bodies[0]["body"] == "projectile");
    CHECK(bodies[4]["body"] == "plate");
    std::size_t offGridCount = 0, erodedCount = 0, keptCount = 0;
    for (const auto& b : bodies) {
      offGridCount += b["off_grid"]["particles"].get<std::size_t>();
      erodedCount += b["eroded"]["particles"].get<std::size_t>();
      keptCount += b["eroded_kept"]["particles"].get<std::size_t>();
      // Each point off the grid went through one face (here spray off the front, z+, and past the free edge, r+).
      double byFace = 0;
      for (const auto& [face, kg] : b["off_grid"]["mass_by_face_kg"].items()) {
        CHECK((face == "r+" || face == "z+" || face == "z-"));
        byFace += kg.get<double>();
      }
      CHECK(byFace == doctest::Approx(b["off_grid"]["mass_kg"].get<double>()));
    }
    CHECK(offGridCount + erodedCount == r.summary["inactive_particles"].get<std::size_t>());
    CHECK(erodedCount == removedInside);
    CHECK(keptCount == kept);
  }
}

// First law: nothing enters the model after the impact, so kinetic + internal energy + the contact's and the
// non-reflecting edges' tallies stay at the projectile's kinetic energy. Seed 000's fabric target with every layer a
// body of its own (multi-field contact), 1 mm at 3.09 km/s, axisymmetric at the file's 0.1 mm, 12 us. Measured:
// 99.8 % (per-node contact strain) and 100.3 % (per-particle). The tally that missed the strain work of the
// corrected velocities and the sliver correction's work ended at 84.4 % and 73.7 %.
TEST_CASE("impact: with the multi-field contact the energy balance of a layered target closes, both contact strains") {
  const std::string path = std::string(BLT_DATA_DIR) + "/scenarios/fabric_al_corrected.toml";
  for (const std::string strain : {"per-node", "per-particle"}) {
    CAPTURE(strain);
    const ImpactScenario sc = loadScenario(path, {"solver.contact=multi-field", std::string("solver.contact_strain=") + strain,
                                                  "projectile.diameter=1mm", "projectile.velocity=3.09km/s"});
    ImpactModel<2> m = buildImpactModel<2>(sc, 1);
    REQUIRE(m.solver->bodyCount() == 5);
    const double initial = m.solver->energies().total();
    while (m.solver->time() < 12e-6) m.solver->step();
    const EnergyBalance e = m.solver->energies();
    MESSAGE(strain << ": kinetic " << e.kinetic / initial * 100 << " %, internal " << e.internal / initial * 100
                   << " %, contact " << e.contactDissipation / initial * 100 << " %, boundary "
                   << e.boundaryWork / initial * 100 << " %, total " << e.total() / initial * 100 << " %");
    CHECK(e.contactDissipation > 0.1 * initial);  // the contact did work: the check has something to check
    CHECK(e.total() == relApprox(initial, 0.01));
  }
}

// The multi-field contact may take energy but never give it. In the MUSL step the strain increment takes, at the
// nodes the contact corrected, the velocity that moved the particles, and elsewhere the plain remap of their new
// velocities; with those, kinetic + internal energy cannot rise in a step (docs/validation/README.md, stop 43).
// Seed 003's T2T2 (two clamped Q235 plates in contact) struck at 150 m/s, coarse (0.5 mm points, 1 mm cells), 100 us:
// with the remap corrected too (the step before stop 43) its energy history rose to 100.52 % of the impact energy.
TEST_CASE("impact: the multi-field contact gives no energy to two clamped plates in contact") {
  const std::string path = std::string(BLT_DATA_DIR) + "/scenarios/q235_T2T2.toml";
  const ImpactScenario sc = loadScenario(path, {"projectile.velocity=150m/s", "resolution.particle_spacing=0.5mm",
                                                "resolution.cell_size=1mm"});
  ImpactModel<2> m = buildImpactModel<2>(sc, 1);
  REQUIRE(m.solver->bodyCount() == 3);
  const double initial = m.solver->energies().kinetic;
  double highest = 0;
  while (m.solver->time() < 100e-6) {
    m.solver->step();
    const EnergyBalance e = m.solver->energies();
    highest = std::max(highest, e.kinetic + e.internal);
  }
  const EnergyBalance e = m.solver->energies();
  MESSAGE("highest kinetic + internal " << highest / initial * 100 << " % of the impact energy; at 100 us "
                                        << (e.kinetic + e.internal) / initial * 100 << " %, contact tally "
                                        << e.contactDissipation / initial * 100 << " %");
  CHECK(e.contactDissipation > 0.01 * initial);  // the contact acted: the check has something to check
  CHECK(highest <= 1.0005 * initial);
}

TEST_CASE("impact: a run killed after a checkpoint and resumed ends exactly as the uninterrupted run") {
  // Reference: the uninterrupted run of the same scenario (one thread, so both are bit for bit reproducible).
  // The interrupted run stops at a step limit twice; the second checkpoint is then replaced by the first, as a
  // kill after the first would leave it, with energy and verdict rows written past it that must be dropped.
  // A steel sphere through 0.2 mm of plate settles at about 21.0 us: perforated, and stopped once the mass behind
  // the wall, the residual velocity and the hole have held still over the last half of the run, a look back
  // past the first checkpoint (at 60 % of the steps), so the earlier verdicts must come back with it.
  const std::vector<std::string> settings = {"target.layer.1.thickness=0.2mm", "projectile.velocity=4km/s",
                                             "projectile.material=steel_4340", "run.max_time=30us"};
  const ImpactScenario sc = parseScenario(plateScenario(), "plate.toml", settings);
  const fs::path base = fs::temp_directory_path() / ("blt_test_resume_" + std::to_string(::getpid()));
  fs::remove_all(base);
  ImpactRunOptions o;
  o.threads = 1;
  o.outputDirectory = (base / "straight").string();
  const ImpactResult straight = runImpact(sc, o);
  REQUIRE(straight.verdict.perforated);
  REQUIRE(std::string(toString(straight.status)) == "stopped");  // settled: the steadiness history matters to when it stops
  const long steps = straight.summary["steps"].get<long>();
  REQUIRE(steps > 100);

  const fs::path dir = base / "interrupted";
  o.outputDirectory = dir.string();
  o.checkpointSeconds = 1e6;  // only the one written at the end of each part
  o.maxSteps = steps * 6 / 10;
  const ImpactResult first = runImpact(sc, o);
  CHECK(std::string(toString(first.status)) == "step-limit");
  fs::copy_file(dir / "plate_checkpoint.bin", base / "first_checkpoint.bin");
  o.resume = true;
  o.maxSteps = steps * 2 / 10;
  const ImpactResult second = runImpact(sc, o);
  CHECK(second.summary["steps"] == steps * 6 / 10 + steps * 2 / 10);
  CHECK(second.resumedAt == first.endTime);
  fs::copy_file(base / "first_checkpoint.bin", dir / "plate_checkpoint.bin", fs::copy_options::overwrite_existing);
  o.maxSteps = -1;
  const ImpactResult resumed = runImpact(sc, o);

  CHECK(resumed.resumedAt == first.endTime);
  CHECK(std::string(toString(resumed.status)) == std::string(toString(straight.status)));
  CHECK(resumed.message.find(straight.message) == 0);  // with "; resumed from a checkpoint at ..." after it
  for (const char* key : {"steps", "time_s", "perforated", "settled", "residual_velocity_m_s",
                          "mass_behind_rear_wall_fraction", "hole_size_mm", "opening_size_mm", "energy_initial",
                          "energy_final", "rearward_kinetic_energy_fraction"})
    CHECK_MESSAGE(resumed.summary[key] == straight.summary[key], key);
  CHECK(readText(dir / "plate_energy.csv") == readText(base / "straight" / "plate_energy.csv"));
  CHECK(readText(dir / "verdict_history.csv") == readText(base / "straight" / "verdict_history.csv"));
  // The frames: the uninterrupted run's, and the last state of the first part where it stopped at the limit.
  const std::vector<std::string> framesStraight = pvdTimes(base / "straight" / "plate.pvd");
  const std::vector<std::string> framesResumed = pvdTimes(dir / "plate.pvd");
  CHECK(framesResumed.size() == framesStraight.size() + 1);
  for (const std::string& t : framesStraight)
    CHECK(std::find(framesResumed.begin(), framesResumed.end(), t) != framesResumed.end());
  for (std::size_t k = 0; k < framesResumed.size(); ++k) {
    char name[32];
    std::snprintf(name, sizeof name, "plate_%04zu.vtu", k);
    CHECK_MESSAGE(fs::exists(dir / name), name);
  }
  char past[32];
  std::snprintf(past, sizeof past, "plate_%04zu.vtu", framesResumed.size());
  CHECK_FALSE(fs::exists(dir / past));

  // Another shot with the same particle count is another model: refused, the checkpoint named.
  o.maxSteps = 1;
  std::vector<std::string> other = settings;
  other.push_back("projectile.velocity=4.1km/s");
  const std::string refused = messageOf([&] { runImpact(parseScenario(plateScenario(), "plate.toml", other), o); });
  CHECK(contains(refused, "plate_checkpoint.bin"));
  CHECK(contains(refused, "another model"));
  fs::remove_all(base);
}

TEST_CASE("blt sim run --resume runs a finished run longer, to the state of one run to the longer end time") {
  // Reference: the same shot run straight to 2 us. The shot at 3 km/s through 4 mm of plate does not settle by
  // then, so both runs go to the end time and must end in the same state.
  const fs::path base = fs::temp_directory_path() / ("blt_test_longer_" + std::to_string(::getpid()));
  fs::remove_all(base);
  fs::create_directories(base);
  const fs::path file = base / "plate.toml";
  {
    std::ofstream out(file);
    out << plateScenario();
  }
  const std::string shot = "sim run '" + file.string() +
                           "' --set resolution.particle_spacing=0.2mm --set target.layer.1.thickness=4mm --threads 1 ";
  const BltRun straight = runBlt(shot + "--set run.max_time=2us --json");
  REQUIRE(straight.status == 0);
  const auto a = nlohmann::json::parse(straight.output.substr(straight.output.find('{')));
  REQUIRE(a["status"] == "completed");
  const std::string out = " --out '" + (base / "run").string() + "'";
  REQUIRE(runBlt(shot + "--set run.max_time=1us --checkpoint-every 1h" + out).status == 0);
  CHECK(fs::exists(base / "run" / "plate_checkpoint.bin"));
  const BltRun longer = runBlt(shot + "--set run.max_time=2us --resume --json" + out);
  REQUIRE(longer.status == 0);
  const auto b = nlohmann::json::parse(longer.output.substr(longer.output.find('{')));
  CHECK(b["resumed_at_time_s"].get<double>() == doctest::Approx(1e-6).epsilon(0.01));
  for (const char* key : {"steps", "time_s", "perforated", "energy_final", "hole_size_mm", "kinetic_energy_fraction"})
    CHECK_MESSAGE(b[key] == a[key], key);

  // Bad requests say which flag and what is wanted.
  const BltRun noDir = runBlt(shot + "--resume");
  CHECK(noDir.status != 0);
  CHECK(contains(noDir.output, "--resume"));
  CHECK(contains(noDir.output, "--out DIR"));
  const BltRun none = runBlt(shot + "--resume --out '" + (base / "empty").string() + "'");
  CHECK(none.status != 0);
  CHECK(contains(none.output, "plate_checkpoint.bin"));
  CHECK(contains(runBlt(shot + "--ensemble 2 --checkpoint-every 1min" + out).output, "not an ensemble"));
  CHECK(contains(runBlt(shot + "--checkpoint-every 3mm" + out).output, "--checkpoint-every"));
  fs::remove_all(base);
}
