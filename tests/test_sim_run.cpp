// The solver's run driver, output files, contact and the `blt sim` / `blt bench` command lines (issue 4).
#include <doctest/doctest.h>
#include <algorithm>

#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <random>
#include <sstream>

#include "approx.hpp"
#include "sim_materials.hpp"
#include "blt/core/materials.hpp"
#include "blt/sim/cases.hpp"
#include "blt/sim/contact.hpp"
#include "blt/sim/geometry.hpp"
#include "blt/sim/run.hpp"
#include "run_blt.hpp"

using namespace blt::sim;
namespace fs = std::filesystem;

namespace {
fs::path freshDir(const std::string& name) {
  const fs::path dir = fs::temp_directory_path() / ("blt_test_" + name + "_" + std::to_string(::getpid()));
  fs::remove_all(dir);
  return dir;
}

std::string slurp(const fs::path& p) {
  std::ifstream in(p);
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

// Two elastic spheres on the axis moving towards each other, one body each (multi-field contact).
std::unique_ptr<Solver<2>> twoSpheres(double speed, SolverOptions o = {}) {
  const double R = 5e-3, s = R / 10, h = 2 * s;
  GridSpec<2> g;
  g.cellSize = h;
  g.lower = Vec<2>(0, -2 * R - 4 * h);
  g.upper = Vec<2>(R + 4 * h, 2 * R + 4 * h);
  g.boundary = {BoundaryKind::symmetry, BoundaryKind::free, BoundaryKind::free, BoundaryKind::free};
  o.viscosity = {0, 0};
  auto solver = std::make_unique<Solver<2>>(g, o, std::vector<SolidMaterial>{
                                                      makeSolidMaterial(blt::parseMaterial(kElasticAluminium, "e", "e"))});
  BodyFill<2> a;
  a.spacing = s;
  a.velocity = Vec<2>(0, -speed);
  fillSphere<2>(solver->particles(), solver->materials()[0], a, Vec<2>(0, R + s), R);
  BodyFill<2> b = a;
  b.body = 1;
  b.velocity = Vec<2>(0, speed);
  fillSphere<2>(solver->particles(), solver->materials()[0], b, Vec<2>(0, -R - s), R);
  solver->initialise();
  return solver;
}

// Every particle at the same position with the same stress, bit for bit.
bool sameState(const Solver<2>& a, const Solver<2>& b) {
  bool same = a.particles().size() == b.particles().size();
  for (std::size_t i = 0; same && i < a.particles().size(); ++i)
    same = a.particles().position[i] == b.particles().position[i] && a.particles().stress[i] == b.particles().stress[i];
  return same;
}

Vec<2> bodyMomentum(const Solver<2>& s, int body) {
  Vec<2> p = Vec<2>::Zero();
  for (std::size_t i = 0; i < s.particles().size(); ++i)
    if (s.particles().body[i] == body) p += s.particles().mass[i] * s.particles().velocity[i];
  return p;
}

// What a head-on collision of the two spheres did, step by step, until `endTime`.
struct SphereCollision {
  double highestEnergy = 0;      // largest kinetic + internal, J
  double closestGap = 1e9;       // smallest axial gap between the two bodies' particle centres, m
  double largestImbalance = 0;   // largest |total axial momentum| (zero by Newton's third law), kg m/s
};
SphereCollision collide(Solver<2>& solver, double endTime) {
  SphereCollision c;
  while (solver.time() < endTime) {
    solver.step();
    const EnergyBalance e = solver.energies();
    c.highestEnergy = std::max(c.highestEnergy, e.kinetic + e.internal);
    double lowestA = 1e9, highestB = -1e9;
    const auto& P = solver.particles();
    for (std::size_t i = 0; i < P.size(); ++i) {
      if (P.body[i] == 0) lowestA = std::min(lowestA, P.position[i][1]);
      else highestB = std::max(highestB, P.position[i][1]);
    }
    c.closestGap = std::min(c.closestGap, lowestA - highestB);
    const double imbalance = std::fabs(bodyMomentum(solver, 0)[1] + bodyMomentum(solver, 1)[1]);
    c.largestImbalance = std::max(c.largestImbalance, imbalance);
  }
  return c;
}
}  // namespace

TEST_SUITE("sim") {

TEST_CASE("sim: multi-field contact keeps two colliding bodies apart, conserves momentum and lets them rebound") {
  auto solver = twoSpheres(20.0);
  const double p0 = bodyMomentum(*solver, 0)[1];
  REQUIRE(p0 < 0);
  const double e0 = solver->energies().kinetic;
  const SphereCollision c = collide(*solver, 40e-6);
  const double highest = c.highestEnergy;
  // Newton's third law at the contact nodes: the total axial momentum stays zero.
  CHECK(c.largestImbalance < 1e-9 * std::fabs(p0));
  CHECK(c.closestGap > 0);  // particle centres of the two bodies never cross
  // An elastic collision cannot create energy (it gained 10 % before the MUSL remap kept contact-corrected
  // velocities); what the contact loses is reported, not bounded here.
  MESSAGE("largest kinetic + internal " << highest / e0 * 100 << " % of the initial kinetic energy; after: "
                                        << (solver->energies().kinetic + solver->energies().internal) / e0 * 100
                                        << " %");
  CHECK(highest < 1.01 * e0);
  // Both bodies have turned round (elastic rebound): the upper one now moves up.
  CHECK(bodyMomentum(*solver, 0)[1] > 0.5 * std::fabs(p0));
}

// An elastic block strikes an elastic plate flat-on at 45 degrees (plane strain, plate on a rigid support).
// Frictionless contact leaves the tangential momentum unchanged; with mu = 0.2 friction takes some of it. (The
// exact Coulomb bound holds node by node, tested below; summed over the block it is approached within a few
// percent, since the normals at the block's corners are tilted.)
Vec<2> discImpulse(double friction, Vec<2>* normalAndTangential) {
  const double R = 3e-3, s = R / 8, h = 2 * s, v = 10.0;
  GridSpec<2> g;
  g.cellSize = h;
  g.lower = Vec<2>(-4 * R, -R);
  g.upper = Vec<2>(6 * R, 3 * R);
  g.boundary = {BoundaryKind::free, BoundaryKind::free, BoundaryKind::symmetry, BoundaryKind::free};
  SolverOptions o;
  o.axisymmetric = false;
  o.contact.friction = friction;
  o.viscosity = {0, 0};
  Solver<2> solver(g, o, {makeSolidMaterial(blt::parseMaterial(kElasticAluminium, "e", "e"))});
  BodyFill<2> disc;
  disc.spacing = s;
  disc.axisymmetric = false;
  disc.velocity = Vec<2>(v, -v);
  fillBox<2>(solver.particles(), solver.materials()[0], disc, Vec<2>(-R, s), Vec<2>(R, 2 * R + s));
  BodyFill<2> plate = disc;
  plate.body = 1;
  plate.velocity = Vec<2>::Zero();
  fillBox<2>(solver.particles(), solver.materials()[0], plate, Vec<2>(-4 * R, -R), Vec<2>(6 * R, 0));
  solver.initialise();
  const Vec<2> before = [&] {
    Vec<2> p = Vec<2>::Zero();
    for (std::size_t i = 0; i < solver.particles().size(); ++i)
      if (solver.particles().body[i] == 0) p += solver.particles().mass[i] * solver.particles().velocity[i];
    return p;
  }();
  while (solver.time() < 12e-6) solver.step();
  Vec<2> after = Vec<2>::Zero();
  for (std::size_t i = 0; i < solver.particles().size(); ++i)
    if (solver.particles().body[i] == 0) after += solver.particles().mass[i] * solver.particles().velocity[i];
  *normalAndTangential = Vec<2>(std::fabs(after[1] - before[1]), std::fabs(after[0] - before[0]));
  return before;
}

TEST_CASE("sim: with the strain from corrected velocities per particle, two elastic spheres rebound apart without gaining energy") {
  // ContactStrain::perParticle: a particle touching a contact-corrected node takes its strain increment from the
  // corrected velocities at all its nodes, and the remap is not corrected. Taking the remap's velocities without the
  // per-particle switch gained 11.6 % here; the bound is that of the per-node default above.
  SolverOptions o;
  o.contact.strain = ContactStrain::perParticle;
  auto solver = twoSpheres(20.0, o);
  const double p0 = bodyMomentum(*solver, 0)[1];
  const double e0 = solver->energies().kinetic;
  const SphereCollision c = collide(*solver, 40e-6);
  MESSAGE("per particle: largest kinetic + internal " << c.highestEnergy / e0 * 100
                                                      << " % of the initial kinetic energy; largest momentum imbalance "
                                                      << c.largestImbalance / std::fabs(p0) << " of p0");
  CHECK(c.closestGap > 0);
  CHECK(c.highestEnergy < 1.01 * e0);
  CHECK(bodyMomentum(*solver, 0)[1] > 0.5 * std::fabs(p0));
  // The contact's exchange sums to zero as before. What is lost (at most 6.6e-9 of p0 here; 8e-16 with the per-node
  // default) is the force at nodes below the grid's mass floor (1e-9 of the lightest particle's mass), whose update
  // the grid skips: with the floor at 1e-30 the loss is 4e-16. Per-particle stresses put more force there.
  CHECK(c.largestImbalance < 1e-8 * std::fabs(p0));
}

TEST_CASE("sim: contact friction obeys Coulomb's bound on the tangential impulse") {
  Vec<2> slip, stick;
  const Vec<2> p0 = discImpulse(0.0, &slip);
  discImpulse(0.2, &stick);
  MESSAGE("mu = 0: normal impulse " << slip[0] << ", tangential " << slip[1] << "; mu = 0.2: normal " << stick[0]
                                    << ", tangential " << stick[1] << " (N s per m)");
  CHECK(slip[0] > 1.5 * std::fabs(p0[1]));  // the disc has bounced: the normal impulse exceeds its momentum
  CHECK(slip[1] < 0.01 * slip[0]);
  CHECK(stick[1] > 0.05 * stick[0]);
}

// The nodal correction worked by hand: masses 1 and 3, velocities (1, -2) and (0, 1), normals -y and +y.
// Centre of mass (0.25, 0.25); body a approaches with normal speed 2.25 and slides (0.2 x 2.25 < 0.75), body b
// with 0.75 and slides (0.15 < 0.25). Coulomb: tangential change = mu x normal change; momentum conserved.
TEST_CASE("sim: nodal contact correction: no interpenetration, Coulomb sliding, stick, separation") {
  const double m[2] = {1.0, 3.0};
  const Vec<2> normal[2] = {Vec<2>(0, -1), Vec<2>(0, 1)};
  const int ids[2] = {0, 1};
  Vec<2> v[2] = {Vec<2>(1, -2), Vec<2>(0, 1)};
  correctContact<2>(v, m, normal, ids, 2, 0.2);
  CHECK(v[0][0] == relApprox(0.55, 1e-12));
  CHECK(v[0][1] == relApprox(0.25, 1e-12));
  CHECK(v[1][0] == relApprox(0.15, 1e-12));
  CHECK(v[1][1] == relApprox(0.25, 1e-12));
  const Vec<2> p = m[0] * v[0] + m[1] * v[1];
  CHECK(p[0] == relApprox(1.0, 1e-12));
  CHECK(p[1] == relApprox(1.0, 1e-12));
  // Enough friction to stop the sliding: both take the centre-of-mass velocity.
  Vec<2> w[2] = {Vec<2>(1, -2), Vec<2>(0, 1)};
  correctContact<2>(w, m, normal, ids, 2, 1.0);
  CHECK((w[0] - Vec<2>(0.25, 0.25)).norm() < 1e-12);
  CHECK((w[1] - Vec<2>(0.25, 0.25)).norm() < 1e-12);
  // Moving apart: untouched.
  Vec<2> u[2] = {Vec<2>(0.3, 1), Vec<2>(0, -1)};
  correctContact<2>(u, m, normal, ids, 2, 0.2);
  CHECK(u[0] == Vec<2>(0.3, 1));
  CHECK(u[1] == Vec<2>(0, -1));
}

// Three bodies at one node, worked by hand: masses 1, 1, 2, velocities (0, -1), (0, 1), (1, 0), normals -y, +y and
// +x (not opposite pairs, as at a node shared by a projectile, a liner and a plate). Centre of mass (0.5, 0); all
// three approach; with mu = 0 bodies 1 and 2 lose their normal speed 1 and go to (0, 0), body 3 its 0.5 and goes to
// (0.5, 0). That changes the momentum by (0, 1) + (0, -1) + 2 (-0.5, 0) = (-1, 0), given back as (0.25, 0) to each.
// Reference: momentum conservation (the total stays (2, 0)) with the relative velocities of the correction kept.
TEST_CASE("sim: nodal contact among three bodies conserves momentum") {
  const double m[3] = {1.0, 1.0, 2.0};
  const Vec<2> normal[3] = {Vec<2>(0, -1), Vec<2>(0, 1), Vec<2>(1, 0)};
  const int ids[3] = {0, 1, 2};
  Vec<2> v[3] = {Vec<2>(0, -1), Vec<2>(0, 1), Vec<2>(1, 0)};
  correctContact<2>(v, m, normal, ids, 3, 0.0);
  CHECK((v[0] - Vec<2>(0.25, 0)).norm() < 1e-12);
  CHECK((v[1] - Vec<2>(0.25, 0)).norm() < 1e-12);
  CHECK((v[2] - Vec<2>(0.75, 0)).norm() < 1e-12);
  const Vec<2> p = m[0] * v[0] + m[1] * v[1] + m[2] * v[2];
  CHECK((p - Vec<2>(2, 0)).norm() < 1e-12);
}

// Worked by hand: a sliver (mass 0.5) whose momentum velocity is (1, -3) approaches a body below it (sliver normal
// (0, -1)) whose centre of mass moves at (0, -1): it loses the approach, -2, from its own (ill-defined) nodal
// velocity (5, 40) -> (5, 42), and the momentum it lost, 0.5 x (0, 2), is returned for the struck body. Moving
// away it keeps it; inside a body (no normal) it loses all its relative velocity, (1, -2).
TEST_CASE("sim: a sliver may not enter another body, corrected from its momentum velocity") {
  const int ids[1] = {0};
  const double m[1] = {0.5};
  const Vec<2> momentumVelocity[1] = {Vec<2>(1, -3)};
  Vec<2> v[1] = {Vec<2>(5, 40)};
  const Vec<2> taken = correctSlivers<2>(v, m, momentumVelocity, ids, 1, Vec<2>(0, -1), Vec<2>(0, -1));
  CHECK((v[0] - Vec<2>(5, 42)).norm() < 1e-12);
  CHECK((taken - Vec<2>(0, 1)).norm() < 1e-12);
  const Vec<2> away[1] = {Vec<2>(1, 3)};
  Vec<2> w[1] = {Vec<2>(5, 40)};
  CHECK(correctSlivers<2>(w, m, away, ids, 1, Vec<2>(0, -1), Vec<2>(0, -1)).isZero(0.0));
  CHECK(w[0] == Vec<2>(5, 40));
  Vec<2> u[1] = {Vec<2>(5, 40)};
  const Vec<2> inside = correctSlivers<2>(u, m, momentumVelocity, ids, 1, Vec<2>(0, -1), Vec<2>::Zero());
  CHECK((u[0] - Vec<2>(4, 42)).norm() < 1e-12);
  CHECK((inside - Vec<2>(-0.5, 1)).norm() < 1e-12);
}

namespace {
// Light spray (isolated points, every third lattice point of one row, of 1 % of the plate's density) flying at
// `speed` towards a 2 mm aluminium plate 0.4 mm below it; axisymmetric, 0.1 mm points in 0.2 mm cells. Each spray
// point has only a few per cent of a node's mass or volume: a sliver where it meets the plate.
std::unique_ptr<Solver<2>> sprayOntoPlate(double speed, const std::string& sprayModulus, const SolverOptions& o) {
  const double s = 0.1e-3, h = 2 * s;
  GridSpec<2> g;
  g.cellSize = h;
  g.lower = Vec<2>(0, -3e-3);
  g.upper = Vec<2>(3e-3, 1.5e-3);
  g.boundary = {BoundaryKind::symmetry, BoundaryKind::free, BoundaryKind::free, BoundaryKind::free};
  std::string spray = kElasticAluminium;
  spray.replace(spray.find("2700 kg/m3"), 10, "27 kg/m3");
  spray.replace(spray.find("70 GPa"), 6, sprayModulus);
  auto solver = std::make_unique<Solver<2>>(
      g, o, std::vector<SolidMaterial>{makeSolidMaterial(blt::parseMaterial(kElasticAluminium, "al", "al")),
                                       makeSolidMaterial(blt::parseMaterial(spray, "spray", "spray"))});
  BodyFill<2> plate;
  plate.spacing = s;
  plate.body = 1;
  fillBox<2>(solver->particles(), solver->materials()[0], plate, Vec<2>(0, -2e-3), Vec<2>(3e-3, 0));
  BodyFill<2> ring = plate;
  ring.body = 0;
  ring.material = 1;
  ring.velocity = Vec<2>(0, -speed);
  int k = 0;
  fillRegion<2>(solver->particles(), solver->materials()[1], ring, Vec<2>(0, 0.4e-3), Vec<2>(1.5e-3, 0.5e-3),
                [&](const Vec<2>&) { return k++ % 3 == 1; });
  solver->initialise();
  return solver;
}
}  // namespace

// Spray at 3 km/s: with contact among real shares only it went through the plate. Reference: impenetrability; no
// spray point may end up deeper than one cell into the plate.
TEST_CASE("sim: light spray does not pass through a heavy plate") {
  auto solver = sprayOntoPlate(3000, "70 GPa", SolverOptions{});
  while (solver->time() < 1.0e-6) solver->step();  // 3 mm of flight: the plate is 2 mm thick
  const auto& P = solver->particles();
  double deepest = 1;
  for (std::size_t p = 0; p < P.size(); ++p)
    if (P.body[p] == 0 && P.active[p]) deepest = std::min(deepest, P.position[p][1]);
  CHECK(deepest > -solver->grid().cellSize);
}

// The same light spray, slower and without bulk viscosity, so that the sliver correction is what stops it: the spray's
// kinetic energy is all the energy there is, and by the first law kinetic + internal + the tallied contact and
// boundary work must stay at it. Measured: 99.9 %; before the sliver correction's work was tallied, 1.8 %.
// The spray is soft (a gas-like 70 kPa modulus): the points' nodal velocities, corrected at some nodes and not at
// others, deform them, and aluminium's stiffness would turn that into strain energy far above their kinetic.
TEST_CASE("sim: the work of the sliver correction is in the contact tally, so light spray stopped by a plate keeps the balance") {
  SolverOptions o;
  o.viscosity = {0.0, 0.0};
  auto solver = sprayOntoPlate(300, "70 kPa", o);
  const double initial = solver->energies().total();
  while (solver->time() < 3e-6) solver->step();  // 0.9 mm of flight: the spray reaches the plate at 0.35 mm
  const EnergyBalance e = solver->energies();
  const auto& P = solver->particles();
  double sprayMomentum = 0, sprayMass = 0;
  for (std::size_t p = 0; p < P.size(); ++p)
    if (P.body[p] == 0) sprayMomentum += P.mass[p] * P.velocity[p][1], sprayMass += P.mass[p];
  MESSAGE("spray speed " << -sprayMomentum / sprayMass << " m/s (from 300); kinetic " << e.kinetic / initial * 100
                         << " %, internal " << e.internal / initial * 100 << " %, contact " << e.contactDissipation / initial * 100
                         << " %, total " << e.total() / initial * 100 << " %");
  CHECK(-sprayMomentum / sprayMass < 0.5 * 300);  // the spray was stopped, mostly: there was work to tally
  CHECK(e.contactDissipation > 0);
  CHECK(e.total() == relApprox(initial, 0.02));
}

TEST_CASE("sim: without contact correction the single-field mode makes the bodies one") {
  SolverOptions o;
  o.contact.mode = ContactMode::singleField;
  auto solver = twoSpheres(20.0, o);
  CHECK(solver->bodyCount() == 1);
}

TEST_CASE("sim: a run writes a ParaView series, an energy history and a summary") {
  const auto dir = freshDir("run");
  const auto copper = blt::MaterialLibrary::load().get("cu_ofhc");
  TaylorBarCase c;
  c.particlesPerDiameter = 6;
  auto solver = makeTaylorBarAxisymmetric(c, copper);
  RunOptions ro;
  ro.endTime = 10e-6;
  ro.outputDirectory = dir.string();
  ro.name = "bar";
  ro.frames = 2;
  ro.energySamples = 10;
  const RunResult r = run<2>(*solver, ro);
  CHECK(std::string(toString(r.status)) == "completed");
  CHECK(fs::exists(dir / "bar.pvd"));
  CHECK(fs::exists(dir / "bar_0000.vtu"));
  CHECK(fs::exists(dir / "bar_0002.vtu"));
  const std::string pvd = slurp(dir / "bar.pvd");
  CHECK(pvd.find("bar_0002.vtu") != std::string::npos);
  const std::string vtu = slurp(dir / "bar_0000.vtu");
  for (const char* field : {"velocity_m_s", "stress_Pa", "pressure_Pa", "specific_energy_J_kg", "temperature_K",
                            "plastic_strain", "damage", "material", "body"})
    CHECK_MESSAGE(vtu.find(std::string("Name=\"") + field + "\"") != std::string::npos, std::string(field));
  const std::string csv = slurp(dir / "bar_energy.csv");
  CHECK(csv.rfind("step,time_s,time_step_s,kinetic_J,internal_J,plastic_work_J,viscous_work_J,", 0) == 0);
  CHECK(std::count(csv.begin(), csv.end(), '\n') >= 11);
  const auto summary = nlohmann::json::parse(slurp(dir / "bar_summary.json"));
  CHECK(summary["status"] == "completed");
  CHECK(summary["solver"]["shape_function"] == "uGIMP");
  CHECK(summary["solver"]["update_scheme"] == "MUSL");
  CHECK(summary["geometry"] == "axisymmetric");
  fs::remove_all(dir);
}

TEST_CASE("sim: an unstable run stops with where and when, and keeps what it wrote") {
  const auto dir = freshDir("unstable");
  SolverOptions o;
  o.timeStepSafety = 2.5;  // far past the Courant limit of seed 001 Eq. 8
  o.viscosity = {0, 0};
  auto solver = twoSpheres(20.0, o);
  RunOptions ro;
  ro.endTime = 200e-6;
  ro.outputDirectory = dir.string();
  ro.name = "blowup";
  ro.energySamples = 2000;
  const RunResult r = run<2>(*solver, ro);
  CHECK(std::string(toString(r.status)) == "unstable");
  CHECK(r.message.find("unstable at step") != std::string::npos);
  CHECK(r.message.find(" us") != std::string::npos);
  CHECK(r.time < ro.endTime);
  CHECK(fs::exists(dir / "blowup_energy.csv"));
  CHECK(fs::exists(dir / "blowup.pvd"));
  const auto summary = nlohmann::json::parse(slurp(dir / "blowup_summary.json"));
  CHECK(summary["status"] == "unstable");
  CHECK(summary["message"] == r.message);
  fs::remove_all(dir);
}

TEST_CASE("sim: a run restored from a checkpoint continues exactly as the uninterrupted run") {
  const auto dir = freshDir("checkpoint");
  fs::create_directories(dir);
  const auto copper = blt::MaterialLibrary::load().get("cu_ofhc");
  TaylorBarCase c;
  c.particlesPerDiameter = 6;
  auto straight = makeTaylorBarAxisymmetric(c, copper);
  auto first = makeTaylorBarAxisymmetric(c, copper);
  for (int i = 0; i < 60; ++i) straight->step();
  for (int i = 0; i < 33; ++i) first->step();  // not a multiple of the reordering interval
  const std::string file = (dir / "bar_checkpoint.bin").string();
  writeCheckpoint<2>(file, *first);
  auto resumed = makeTaylorBarAxisymmetric(c, copper);
  readCheckpoint<2>(file, *resumed);
  CHECK(resumed->stepCount() == 33);
  while (resumed->stepCount() < 60) resumed->step();
  CHECK(resumed->time() == straight->time());
  CHECK(sameState(*straight, *resumed));
  // A checkpoint of another scenario is refused with the file named.
  TaylorBarCase other = c;
  other.particlesPerDiameter = 8;
  auto mismatch = makeTaylorBarAxisymmetric(other, copper);
  CHECK_THROWS_WITH_AS(readCheckpoint<2>(file, *mismatch), doctest::Contains("bar_checkpoint.bin"), blt::InputError);
  fs::remove_all(dir);
}

// Threads scatter slab by slab in a fixed colour order, so the nodal sums are added in the same order as in a
// serial run: the result must not depend on the thread count (reproducible campaigns).
TEST_CASE("sim: two threads give bit-identical results to one") {
  const auto lib = blt::MaterialLibrary::load();
  PlateImpactCase c;
  c.velocity = 2000;
  c.projectileDiameter = 2e-3;
  c.projectileLength = 2e-3;
  c.plateRadius = 5e-3;
  c.plateThickness = 2e-3;
  c.spacing = 0.05e-3;
  SolverOptions one, two;
  one.threads = 1;
  two.threads = 2;
  auto serial = makePlateImpactAxisymmetric(c, lib.get("al_2a12"), lib.get("al_5a06"), one);
  auto threaded = makePlateImpactAxisymmetric(c, lib.get("al_2a12"), lib.get("al_5a06"), two);
  REQUIRE(serial->particles().size() >= 4000);  // large enough to run threaded
  for (int i = 0; i < 60; ++i) {
    serial->step();
    threaded->step();
  }
  CHECK(serial->time() == threaded->time());
  CHECK(sameState(*serial, *threaded));
}

namespace {
// uGIMP's definition (Bardenhagen and Kober 2004): the weight of node I is the mean of the linear hat function
// N_I over the particle's domain [x - lp, x + lp], and its gradient is (N_I(x + lp) - N_I(x - lp)) / (2 lp).
// The hat is linear between the nodes, so the trapezoid rule on the pieces split at the nodes is exact.
double hat(double y, double node, double h) { return std::max(0.0, 1.0 - std::fabs(y - node) / h); }
void gimpByDefinition(double x, double lp, double node, double h, double& w, double& g) {
  double cuts[5] = {x - lp, node - h, node, node + h, x + lp};
  std::sort(cuts, cuts + 5);
  double integral = 0;
  for (int i = 0; i + 1 < 5; ++i) {
    const double a = std::clamp(cuts[i], x - lp, x + lp), b = std::clamp(cuts[i + 1], x - lp, x + lp);
    integral += 0.5 * (b - a) * (hat(a, node, h) + hat(b, node, h));
  }
  w = integral / (2 * lp);
  g = (hat(x + lp, node, h) - hat(x - lp, node, h)) / (2 * lp);
}
}  // namespace

TEST_CASE("sim: uGIMP's branch-free stencil equals the function's definition and the per-node form, zeros exactly alike") {
  const double h = 0.2e-3;
  std::mt19937_64 rng(20261207);  // fixed sequence; the top 53 bits give [0, 1)
  const auto uniform = [&] { return static_cast<double>(rng() >> 11) * 0x1.0p-53; };
  std::size_t compared = 0, zeros = 0, badDefinition = 0, badNode = 0, badZero = 0, badSum = 0;
  for (double lpCells : {0.05, 0.25, 0.5}) {
    const double lp = lpCells * h;
    for (int i = 0; i < 20000; ++i) {
      // Mostly anywhere in a 10-cell grid, some on the quarter points and node faces where rounding decides.
      double xi = lp + uniform() * (10 * h - 2 * lp);
      if (i % 4 == 0) xi = (1 + static_cast<int>(uniform() * 8)) * h + (i % 8 == 0 ? lp : -lp);
      const int base = stencilBase(ShapeFunctionKind::uGimp, xi, h, lp, 11);
      double w[3], g[3];
      uGimpStencil(xi, h, lp, base, 1.0 / (h * lp), w, g);
      double sum = 0;
      for (int k = 0; k < 3; ++k) {
        double wd, gd, wn, gn;
        gimpByDefinition(xi, lp, (base + k) * h, h, wd, gd);
        uGimpNode(xi - (base + k) * h, h, lp, 1.0 / h, 1.0 / (h * lp), wn, gn);
        badDefinition += std::fabs(w[k] - wd) > 1e-9 || std::fabs(g[k] - gd) > 1e-9 / h;
        badNode += std::fabs(w[k] - wn) > 1e-12 || std::fabs(g[k] - gn) > 1e-12 / h;
        badZero += (w[k] == 0) != (wn == 0) || (wn == 0 && (g[k] != 0 || gn != 0));
        zeros += w[k] == 0;
        sum += w[k];
        ++compared;
      }
      badSum += std::fabs(sum - 1.0) > 1e-14;
    }
  }
  MESSAGE(compared, " node values compared, ", zeros, " exactly zero");
  CHECK(zeros > 0);
  CHECK(badDefinition == 0);
  CHECK(badNode == 0);
  CHECK(badZero == 0);
  CHECK(badSum == 0);
}

TEST_CASE("sim: a stencil holds every node that carries weight, with uGIMP's weight and gradient there, and 2 nodes per axis where it can") {
  // A block on the fill lattice (quarter points of the cells, where rounding puts the domain's edge on either
  // side of a node) and the same block with every other point moved off it.
  const double s = 0.1e-3, h = 2 * s;
  GridSpec<3> g;
  g.cellSize = h;
  g.lower = Vec<3>::Zero();
  g.upper = Vec<3>(12 * h, 12 * h, 12 * h);
  g.boundary.fill(BoundaryKind::free);
  Solver<3> solver(g, {}, std::vector<SolidMaterial>{makeSolidMaterial(blt::parseMaterial(kElasticAluminium, "e", "e"))});
  BodyFill<3> fill;
  fill.spacing = s;
  fillBox<3>(solver.particles(), solver.materials()[0], fill, Vec<3>(2 * h, 2 * h, 2 * h), Vec<3>(10 * h, 10 * h, 10 * h));
  const std::size_t lattice = solver.particles().size();
  fillBox<3>(solver.particles(), solver.materials()[0], fill, Vec<3>(2 * h, 2 * h, 2 * h), Vec<3>(10 * h, 10 * h, 10 * h));
  auto& P = solver.particles();
  std::mt19937_64 rng(12345);  // its sequence is fixed by the standard; the top 53 bits give [0, 1)
  for (std::size_t p = lattice; p < P.size(); p += 2)
    for (int a = 0; a < 3; ++a) P.position[p][a] += 0.45 * s * (2.0 * static_cast<double>(rng() >> 11) * 0x1.0p-53 - 1.0);
  // And points within a few ulps of a quarter point, where stencilBase rounds down and leaves uGIMP's first node
  // exactly empty: their stencil starts one node later.
  const std::size_t nearQuarter = P.size();
  std::vector<double> emptyFirst;
  const double halfWidth = 0.5 * s;
  for (int i = 1; i < 11; ++i) {
    double x = i * h + halfWidth;
    for (int u = 0; u < 64; ++u) x = std::nextafter(x, 0.0);
    for (int u = 0; u < 128; ++u, x = std::nextafter(x, 1.0)) {
      const int base = stencilBase(ShapeFunctionKind::uGimp, x, h, halfWidth, 13);
      double w, grad;
      uGimpNode(x - base * h, h, halfWidth, 1.0 / h, 1.0 / (h * halfWidth), w, grad);
      if (w == 0 && grad == 0) emptyFirst.push_back(x);
    }
  }
  REQUIRE(!emptyFirst.empty());
  fillBox<3>(P, solver.materials()[0], fill, Vec<3>(2 * h, 2 * h, 2 * h), Vec<3>(4 * h, 4 * h, 4 * h));
  for (std::size_t p = nearQuarter, k = 0; p < P.size(); ++p, ++k)
    P.position[p] = Vec<3>(emptyFirst[k % emptyFirst.size()], emptyFirst[(k / 3) % emptyFirst.size()],
                           emptyFirst[(k / 7) % emptyFirst.size()]);
  solver.initialise();
  solver.computeShapeFunctions();

  const auto& nodes = solver.nodeCounts();
  const long strides[3] = {1, nodes[0], static_cast<long>(nodes[0]) * nodes[1]};
  std::size_t compactOnLattice = 0, compactMoved = 0, moved = 0, shifted = 0, mismatches = 0, notCompacted = 0;
  for (std::size_t p = 0; p < P.size(); ++p) {
    const Stencil<3>& st = solver.stencils()[p];
    const StencilGradient<3>& sg = solver.stencilGradients()[p];
    const bool wasMoved = p >= lattice && p < nearQuarter && (p - lattice) % 2 == 0;
    moved += wasMoved;
    for (int a = 0; a < 3; ++a) {
      const int size = st.size[a];
      REQUIRE((size == 2 || size == 3));
      (wasMoved ? compactMoved : compactOnLattice) += size == 2;
      const int first = static_cast<int>((st.node / strides[a]) % nodes[a]);
      const double xi = P.position[p][a] - g.lower[a], lp = P.halfSize[p][a];
      const int base = stencilBase(ShapeFunctionKind::uGimp, xi, h, lp, nodes[a]);
      double w[3], grad[3];
      for (int k = 0; k < 3; ++k) uGimpNode(xi - (base + k) * h, h, lp, 1.0 / h, 1.0 / (h * lp), w[k], grad[k]);
      const bool compactable = (w[0] == 0 && grad[0] == 0) || (w[2] == 0 && grad[2] == 0);
      // Every node of uGIMP's three, with the stencil's weight there (zero off the stencil): exactly zero where
      // uGimpNode's is, else equal to rounding (the solver evaluates the same function in another form).
      for (int k = 0; k < 3; ++k) {
        const int j = base + k - first;
        const bool held = j >= 0 && j < size;
        const double sw = held ? st.w[a][j] : 0.0, sgrad = held ? sg.g[a][j] : 0.0;
        mismatches += (sw == 0) != (w[k] == 0) || (w[k] == 0 && sgrad != 0) || std::fabs(sw - w[k]) > 1e-12 ||
                      std::fabs(sgrad - grad[k]) > 1e-12 / h;
      }
      mismatches += first < base || first + size > base + 3;
      shifted += first > base;
      notCompacted += compactable && size == 3;
    }
  }
  CHECK(mismatches == 0);
  CHECK(notCompacted == 0);
  MESSAGE(compactOnLattice, " of ", 3 * (P.size() - moved), " axes of lattice and near-quarter points and ", compactMoved,
          " of ", 3 * moved, " axes of moved points have 2 nodes; ", shifted, " axes start one node later");
  CHECK(compactOnLattice > 0);
  CHECK(shifted > 0);
  // A moved point has 2 nodes on an axis when its domain (half a cell wide) lies within one cell: half the
  // positions it can take (uniform over +-0.225 cell about a quarter point).
  CHECK(static_cast<double>(compactMoved) == relApprox(1.5 * static_cast<double>(moved), 0.1));
}

TEST_CASE("sim: the time step follows seed 001 Eq. 8, safety x cell / (c + |v|)") {
  const auto copper = blt::MaterialLibrary::load().get("cu_ofhc");
  TaylorBarCase c;
  c.particlesPerDiameter = 8;
  SolverOptions o;
  o.timeStepSafety = 0.25;
  auto solver = makeTaylorBarAxisymmetric(c, copper, o);
  const SolidMaterial m = makeSolidMaterial(copper);
  const double h = 2 * c.diameter / c.particlesPerDiameter;
  CHECK(solver->timeStep() == relApprox(0.25 * h / (m.referenceWaveSpeed() + c.velocity), 1e-12));
}

namespace {
// A 2 x 2 mm r-z grid whose left face is the axis.
GridSpec<2> axisGrid(double cell) {
  GridSpec<2> g;
  g.cellSize = cell;
  g.lower = Vec<2>(0, 0);
  g.upper = Vec<2>(2e-3, 2e-3);
  g.boundary = {BoundaryKind::symmetry, BoundaryKind::free, BoundaryKind::free, BoundaryKind::free};
  return g;
}

// A block of the MLI card's Mie-Grueneisen foam (seed 000 Table 4: 0.267 g/cm3, c0 = 2000 m/s, s = 1.4), at rest, with
// one point crushed to J = 0.3: near the Hugoniot's singularity (1 - s eta = 0.02) its sound speed is huge.
std::unique_ptr<Solver<2>> crushedFoam(bool failed, SolverOptions o) {
  constexpr const char* card = R"toml(name = "foam"
source = "test"
density = "267 kg/m3"
[elastic]
youngs_modulus = "261 MPa"
poisson_ratio = 0.195
[strength]
model = "elastic"
[eos]
model = "mie-grueneisen"
c0 = "2000 m/s"
s = 1.4
gamma0 = 1.53
)toml";
  const double s = 0.1e-3;
  const GridSpec<2> g = axisGrid(2 * s);
  auto solver = std::make_unique<Solver<2>>(g, o, std::vector<SolidMaterial>{makeSolidMaterial(blt::parseMaterial(card, "foam", "foam"))});
  BodyFill<2> fill;
  fill.spacing = s;
  fillBox<2>(solver->particles(), solver->materials()[0], fill, Vec<2>(0.4e-3, 0.4e-3), Vec<2>(1.6e-3, 1.6e-3));
  solver->initialise();
  auto& P = solver->particles();
  const std::size_t p = P.size() / 2;
  P.deformationGradient[p] = std::cbrt(0.3) * Mat3::Identity();
  P.failed[p] = failed ? 1 : 0;
  return solver;
}
}  // namespace

TEST_CASE("sim: a failed point crushed to a tiny time step is eroded, intact material never is") {
  // The bound is the option's definition: a failed point whose sound speed exceeds erosionSoundSpeed x the fastest
  // undeformed wave speed goes. The crushed point's sound speed is far above it; kept, it cuts the step below.
  SolverOptions o;
  o.erosionSoundSpeed = 4.0;
  const auto limitStep = [&](const Solver<2>& s) {
    return o.timeStepSafety * s.grid().cellSize / (o.erosionSoundSpeed * s.materials()[0].referenceWaveSpeed());
  };
  // The solver may reorder its particles, so the crushed point is found by its state.
  const auto inactiveFailed = [](const Solver<2>& s) {
    int inactive = 0, failed = 0;
    for (std::size_t p = 0; p < s.particles().size(); ++p)
      if (!s.particles().active[p]) ++inactive, failed += s.particles().failed[p];
    return std::pair{inactive, failed};
  };
  auto failed = crushedFoam(true, o);
  const std::size_t all = failed->activeParticles();
  // Marked, to find it again: the eroding step must not store the state it rejects (a pressure far past the
  // Hugoniot's, and with it an energy that would stay in the energy history).
  const std::size_t crushed = failed->particles().size() / 2;
  failed->particles().specificEnergy[crushed] = 1234.5;
  failed->step();
  CHECK(inactiveFailed(*failed) == std::pair{1, 1});
  for (std::size_t p = 0; p < failed->particles().size(); ++p) {
    if (failed->particles().active[p]) continue;
    CHECK(failed->particles().specificEnergy[p] == 1234.5);
    CHECK(failed->particles().stress[p].norm() == 0.0);  // the state before the step: unstressed
  }
  CHECK(failed->timeStep() >= limitStep(*failed));
  failed->step();
  CHECK(failed->activeParticles() == all - 1);

  auto intact = crushedFoam(false, o);
  intact->step();
  CHECK(inactiveFailed(*intact) == std::pair{0, 0});
  CHECK(intact->timeStep() < 0.1 * limitStep(*intact));

  o.erosionSoundSpeed = 0;  // switched off: the failed point stays and sets the step
  auto kept = crushedFoam(true, o);
  kept->step();
  CHECK(inactiveFailed(*kept) == std::pair{0, 0});
  CHECK(kept->timeStep() < 0.1 * limitStep(*kept));
}

TEST_CASE("sim: a point that drifted onto the axis of an axisymmetric run keeps a finite state") {
  // The hoop terms divide by the radius; a centre on the axis (r = 0) gave v_r / 0 before they were bounded by the
  // point's radial half-width.
  const double s = 0.1e-3;
  const GridSpec<2> g = axisGrid(2 * s);
  auto solver = std::make_unique<Solver<2>>(g, SolverOptions{}, std::vector<SolidMaterial>{
                                                                    makeSolidMaterial(blt::parseMaterial(kElasticAluminium, "e", "e"))});
  BodyFill<2> fill;
  fill.spacing = s;
  fill.velocity = Vec<2>(-5.0, 0.0);
  fillBox<2>(solver->particles(), solver->materials()[0], fill, Vec<2>(0.0, 0.4e-3), Vec<2>(1.0e-3, 1.6e-3));
  solver->initialise();
  auto& P = solver->particles();
  for (std::size_t p = 0; p < P.size(); ++p)
    if (P.position[p][0] < s) P.position[p][0] = 0.0;
  for (int k = 0; k < 3; ++k) solver->step();
  CHECK(solver->firstNonFiniteParticle() == -1);
}

TEST_CASE("sim: blt sim example taylor-bar writes its files and reports the shape") {
  const auto dir = freshDir("cli");
  const BltRun r = runBlt("sim example taylor-bar --particles-per-diameter 6 --end-time 20us --frames 2 --json --out '" +
                          dir.string() + "'");
  REQUIRE(r.status == 0);
  const auto doc = nlohmann::json::parse(r.output);
  CHECK(doc["status"] == "completed");
  CHECK(doc["final_length_mm"].get<double>() < 25.4);
  CHECK(doc["measured_length_mm"].get<double>() == relApprox(16.205));
  CHECK(fs::exists(dir / "taylor_bar.pvd"));
  fs::remove_all(dir);
}

TEST_CASE("sim: bad CLI values are errors naming the flag") {
  const BltRun r = runBlt("sim example taylor-bar --velocity 190 --out /tmp/never");
  CHECK(r.status != 0);
  CHECK(r.output.find("--velocity") != std::string::npos);
  const BltRun t = runBlt("sim example taylor-bar --threads -1 --out /tmp/never");
  CHECK(t.status == 2);
  CHECK(t.output.find("--threads") != std::string::npos);
}

TEST_CASE("sim: blt bench sim --case times only the cases named, --disturb moves the points off the lattice, and an unknown case names the cases there are") {
  const BltRun r = runBlt("bench sim --quick --case axisymmetric-jc-mg --threads 1 --json");
  REQUIRE_MESSAGE(r.status == 0, r.output);
  const auto doc = nlohmann::json::parse(r.output);
  REQUIRE(doc["cases"].size() == 1);
  CHECK(doc["cases"][0]["case"] == "axisymmetric-jc-mg");
  CHECK(doc["cases"][0]["steps"] == 50);
  CHECK(doc["cases"][0]["particle_updates_per_s"].get<double>() > 0);
  CHECK_FALSE(doc["cases"][0]["peak_rss_bytes_per_particle"].is_null());  // the first case run owns the peak
  CHECK(doc["cases"][0]["repeats"] == 1);
  // The case's cylinder and plate start on the fill lattice, and most of the plate is still there after 50 steps.
  const double twoNode = doc["cases"][0]["two_node_stencil_fraction"].get<double>();
  CHECK(twoNode > 0.0);
  CHECK(twoNode < 1.0);
  // --repeat 3: three timings of a case built anew each time; the reported rate is their median.
  const BltRun three = runBlt("bench sim --quick --case axisymmetric-jc-mg --threads 1 --repeat 3 --json");
  REQUIRE_MESSAGE(three.status == 0, three.output);
  const auto c3 = nlohmann::json::parse(three.output)["cases"][0];
  auto rates = c3["particle_updates_per_s_runs"].get<std::vector<double>>();
  REQUIRE(rates.size() == 3);
  std::sort(rates.begin(), rates.end());
  CHECK(c3["particle_updates_per_s"].get<double>() == rates[1]);
  CHECK(c3["steps"] == 50);
  // The stages' times are parts of the timed wall time, summed over the three timings.
  double staged = 0;
  for (const auto& [stage, seconds] : c3["stage_seconds"].items()) {
    CHECK(seconds.get<double>() >= 0);
    staged += seconds.get<double>();
  }
  CHECK(c3["stage_seconds"].size() == 7);
  CHECK(staged > 0);
  CHECK(staged <= c3["timed_wall_time_s"].get<double>());
  CHECK(doc["cases"][0]["disturb_cells"] == 0.0);
  // --disturb 0.25: every point moved at random by up to a quarter cell per axis before timing. A uGIMP domain
  // (half a cell wide at 2 points per cell) then lies within one cell, on 2 nodes, with probability 1/2 per
  // axis: a quarter of the points in 2D, against the undisturbed case's lattice.
  const BltRun moved = runBlt("bench sim --quick --case axisymmetric-jc-mg --threads 1 --disturb 0.25 --json");
  REQUIRE_MESSAGE(moved.status == 0, moved.output);
  const auto cm = nlohmann::json::parse(moved.output)["cases"][0];
  CHECK(cm["disturb_cells"] == 0.25);
  CHECK(cm["two_node_stencil_fraction"].get<double>() == relApprox(0.25, 0.12));
  // Each axis on its own: 2 or 3 nodes with probability 1/2 each, 2.5 x 2.5 nodes per point on average.
  CHECK(cm["mean_stencil_nodes"].get<double>() == relApprox(6.25, 0.05));
  CHECK(twoNode > 0.4);
  const BltRun far = runBlt("bench sim --disturb 0.7");
  CHECK(far.status != 0);
  CHECK(far.output.find("--disturb") != std::string::npos);
  const BltRun none = runBlt("bench sim --repeat 0");
  CHECK(none.status != 0);
  CHECK(none.output.find("--repeat") != std::string::npos);
  const BltRun bad = runBlt("bench sim --case 2d");
  CHECK(bad.status == 2);
  CHECK(bad.output.find("--case") != std::string::npos);
  CHECK(bad.output.find("taylor-bar-3d") != std::string::npos);
}

}  // TEST_SUITE
