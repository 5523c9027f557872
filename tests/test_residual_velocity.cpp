// Recht-Ipson / Lambert-Jonas residual velocity: evaluation, the bounded fit and its standard errors, and the
// errors a user sees for bad data. Seed 003 gives fitted constants (Tables 6-8) but no (v_i, v_r) table, so
// the fit is checked against data generated from known constants (several taken from those tables), against
// an independent brute-force search, and its standard errors against an independent finite-difference
// covariance and a Monte Carlo spread.
#include <doctest/doctest.h>

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <numbers>
#include <random>
#include <string>
#include <vector>

#include "approx.hpp"
#include "blt/analytic/residual_velocity.hpp"
#include "blt/core/seeded_gaussian.hpp"

using namespace blt;
using namespace blt::analytic;

namespace {

// Shots at the given velocities from known constants, the model written out here (not the library's), with
// noise of standard deviation `noise` added to the perforating rows. A noisy v_r is kept non-negative.
VelocityData generate(double a, double p, double vbl, const std::vector<double>& velocities, double noise = 0.0,
                      uint32_t seed = 1) {
  SeededGaussian gauss(seed);
  VelocityData data;
  data.source = "generated";
  for (double v : velocities) {
    double vr = v > vbl ? a * std::pow(std::pow(v, p) - std::pow(vbl, p), 1.0 / p) : 0.0;
    if (vr > 0.0) vr = std::max(vr + noise * gauss(), 1e-3);
    data.shots.push_back({v, vr, 0});
  }
  return data;
}

std::vector<double> range(double from, double to, double step) {
  std::vector<double> v;
  for (double x = from; x <= to + 1e-9; x += step) v.push_back(x);
  return v;
}

ResidualVelocityFitOptions withModel(ResidualVelocityModel model) {
  ResidualVelocityFitOptions options;
  options.model = model;
  return options;
}

double modelByHand(double a, double p, double vbl, double v) {
  return v > vbl ? a * std::pow(std::pow(v, p) - std::pow(vbl, p), 1.0 / p) : 0.0;
}

// Brute force: for each (p, v_bl) on a grid the SSR-optimal a is linear least squares, clamped to (0, 1].
double gridMinimumSsr(const VelocityData& data, double pFrom, double pTo, double vFrom, double vTo) {
  double best = 1e300;
  for (double p = pFrom; p <= pTo + 1e-12; p += 0.01) {
    for (double vbl = vFrom; vbl <= vTo + 1e-12; vbl += 0.1) {
      double num = 0.0, den = 0.0;
      for (const auto& s : data.shots) {
        const double g = modelByHand(1.0, p, vbl, s.impactVelocity);
        num += g * s.residualVelocity;
        den += g * g;
      }
      const double a = den > 0.0 ? std::clamp(num / den, 1e-6, 1.0) : 1.0;
      double ssr = 0.0;
      for (const auto& s : data.shots) {
        const double r = modelByHand(a, p, vbl, s.impactVelocity) - s.residualVelocity;
        ssr += r * r;
      }
      best = std::min(best, ssr);
    }
  }
  return best;
}

}  // namespace

TEST_CASE("residual velocity: evaluation equals a hand computation") {
  // Hand computations (Python): 0.8 sqrt(200^2 - 133.8^2) = 118.92198451085486 m/s;
  // 0.9 (200^2.6 - 133.8^2.6)^(1/2.6) = 152.36742072761336 m/s (seed 003 Table 6, T4 constants).
  CHECK(residualVelocity({0.8, 2.0, 133.8}, 200.0) == relApprox(118.92198451085486, 1e-12));
  CHECK(residualVelocity({0.9, 2.6, 133.8}, 200.0) == relApprox(152.36742072761336, 1e-12));
  CHECK(residualVelocity({0.9, 2.6, 133.8}, 133.8) == 0.0);
  CHECK(residualVelocity({0.9, 2.6, 133.8}, 100.0) == 0.0);
  // Seed 002 Eq. 1 is the same relation normalised by v_bl: v_r / v_bl = a ((v_i / v_bl)^p - 1)^(1/p).
  const double normalised = 0.9 * std::pow(std::pow(250.0 / 133.8, 2.6) - 1.0, 1.0 / 2.6);
  CHECK(residualVelocity({0.9, 2.6, 133.8}, 250.0) / 133.8 == relApprox(normalised, 1e-12));
  // v_bl = 0: the projectile only loses the momentum shared with the plug, v_r = a v_i.
  CHECK(residualVelocity({0.75, 3.0, 0.0}, 400.0) == relApprox(300.0, 1e-12));
  // Recht-Ipson a = m_p / (m_p + m_pl): 0.0197 / 0.0246 = 0.8008130081300814 (hand computation).
  CHECK(rechtIpsonA(0.0197, 0.0049) == relApprox(0.8008130081300814, 1e-12));
  CHECK_THROWS_AS(residualVelocity({1.2, 2.0, 100.0}, 200.0), std::invalid_argument);
  CHECK_THROWS_AS(residualVelocity({0.9, 2.0, 100.0}, -1.0), std::invalid_argument);
}

TEST_CASE("residual velocity: exact data give the exact constants back") {
  // Constants of seed 003 Table 6 (experiment, plate T4): a = 0.9, p = 2.6, v_bl = 133.8 m/s. Two stopped
  // shots below v_bl; noise-free residual velocities.
  auto data = generate(0.9, 2.6, 133.8, {100, 120, 140, 150, 170, 200, 240, 280, 330, 400});
  const auto fit = fitResidualVelocity(data, withModel(ResidualVelocityModel::lambertJonas));
  CHECK(fit.a.value == relApprox(0.9, 1e-7));
  CHECK(fit.p.value == relApprox(2.6, 1e-7));
  CHECK(fit.ballisticLimit.value == relApprox(133.8, 1e-7));
  CHECK(fit.rms < 1e-6);
  CHECK(fit.nPoints == 10);
  CHECK(fit.nStopped == 2);
  CHECK(fit.nUsed == 8);
  CHECK(fit.dof == 5);
  CHECK(fit.misclassified == 0);
  CHECK_FALSE(fit.outcomesOverlap);

  // Recht-Ipson (p = 2) on data made with p = 2.
  auto ri = generate(0.736, 2.0, 133.73, {110, 140, 160, 200, 250, 300});
  const auto riFit = fitResidualVelocity(ri, withModel(ResidualVelocityModel::rechtIpson));
  CHECK(riFit.p.value == 2.0);
  CHECK(riFit.p.status == ParameterStatus::fixed);
  CHECK_FALSE(riFit.p.standardError);
  CHECK(riFit.a.value == relApprox(0.736, 1e-7));
  CHECK(riFit.ballisticLimit.value == relApprox(133.73, 1e-7));
}

TEST_CASE("residual velocity: a noisy Lambert-Jonas data set is recovered within 3 standard errors") {
  // a = 0.85, p = 2.3, v_bl = 300 m/s; 210-790 m/s every 20 m/s (no shot exactly at v_bl) (5 stopped, 25 perforating);
  // noise 3 m/s.
  const double sigmaTrue = 3.0;
  auto data = generate(0.85, 2.3, 300.0, range(210, 790, 20), sigmaTrue, 12345);
  const auto fit = fitResidualVelocity(data);
  MESSAGE("a ", fit.a.value, " +/- ", fit.a.standardError.value_or(-1), ", p ", fit.p.value, " +/- ",
          fit.p.standardError.value_or(-1), ", v_bl ", fit.ballisticLimit.value, " +/- ",
          fit.ballisticLimit.standardError.value_or(-1), ", sigma ", fit.sigma.value_or(-1));
  REQUIRE(fit.a.standardError);
  REQUIRE(fit.p.standardError);
  REQUIRE(fit.ballisticLimit.standardError);
  CHECK(fit.a.status == ParameterStatus::fitted);
  CHECK(fit.p.status == ParameterStatus::fitted);
  CHECK(fit.ballisticLimit.status == ParameterStatus::fitted);
  CHECK(std::abs(fit.a.value - 0.85) < 3.0 * *fit.a.standardError);
  CHECK(std::abs(fit.p.value - 2.3) < 3.0 * *fit.p.standardError);
  CHECK(std::abs(fit.ballisticLimit.value - 300.0) < 3.0 * *fit.ballisticLimit.standardError);
  CHECK(fit.nStopped == 5);
  CHECK(fit.dof == 22);
  // sigma^2 dof / sigma_true^2 is chi-square with 22 degrees of freedom; its 0.1 % and 99.9 % quantiles
  // (6.98 and 48.27, standard tables) bound sigma / sigma_true to [0.563, 1.481].
  REQUIRE(fit.sigma);
  CHECK(*fit.sigma / sigmaTrue > 0.563);
  CHECK(*fit.sigma / sigmaTrue < 1.481);

  // The standard errors against an independent computation: a central finite-difference Jacobian of the
  // model written out by hand, sigma^2 (J^T J)^-1 with Eigen.
  const double x[3] = {fit.a.value, fit.p.value, fit.ballisticLimit.value};
  std::vector<const VelocityShot*> used;
  for (const auto& s : data.shots)
    if (s.residualVelocity > 0.0) used.push_back(&s);
  Eigen::MatrixXd J(used.size(), 3);
  for (size_t i = 0; i < used.size(); ++i) {
    for (int k = 0; k < 3; ++k) {
      double hi[3] = {x[0], x[1], x[2]}, lo[3] = {x[0], x[1], x[2]};
      const double h = 1e-6 * std::abs(x[k]);
      hi[k] += h;
      lo[k] -= h;
      J(i, k) = (modelByHand(hi[0], hi[1], hi[2], used[i]->impactVelocity) -
                 modelByHand(lo[0], lo[1], lo[2], used[i]->impactVelocity)) /
                (2.0 * h);
    }
  }
  const Eigen::Matrix3d covariance = (J.transpose() * J).inverse() * (*fit.sigma * *fit.sigma);
  CHECK(*fit.a.standardError == relApprox(std::sqrt(covariance(0, 0)), 1e-4));
  CHECK(*fit.p.standardError == relApprox(std::sqrt(covariance(1, 1)), 1e-4));
  CHECK(*fit.ballisticLimit.standardError == relApprox(std::sqrt(covariance(2, 2)), 1e-4));
}

TEST_CASE("residual velocity: reported standard errors match the Monte Carlo spread of the estimates") {
  // 200 noise realisations of the data set above. With 200 samples the sample standard deviation has a
  // relative standard error of about 1/sqrt(2 * 200) = 5 %; the check allows 4 of those (20 %).
  const int runs = 200;
  std::vector<double> as, ps, vs;
  double seA = 0.0, seP = 0.0, seV = 0.0;
  for (int r = 0; r < runs; ++r) {
    auto data = generate(0.85, 2.3, 300.0, range(210, 790, 20), 3.0, 1000u + static_cast<uint32_t>(r));
    const auto fit = fitResidualVelocity(data);
    REQUIRE(fit.ballisticLimit.standardError);
    as.push_back(fit.a.value);
    ps.push_back(fit.p.value);
    vs.push_back(fit.ballisticLimit.value);
    seA += *fit.a.standardError / runs;
    seP += *fit.p.standardError / runs;
    seV += *fit.ballisticLimit.standardError / runs;
  }
  auto sd = [](const std::vector<double>& v) {
    double mean = 0.0, ss = 0.0;
    for (double x : v) mean += x / v.size();
    for (double x : v) ss += (x - mean) * (x - mean);
    return std::sqrt(ss / (v.size() - 1));
  };
  MESSAGE("Monte Carlo sd / mean stderr: a ", sd(as) / seA, ", p ", sd(ps) / seP, ", v_bl ", sd(vs) / seV);
  CHECK(sd(as) / seA == doctest::Approx(1.0).epsilon(0.2));
  CHECK(sd(ps) / seP == doctest::Approx(1.0).epsilon(0.2));
  CHECK(sd(vs) / seV == doctest::Approx(1.0).epsilon(0.2));
}

TEST_CASE("residual velocity: Recht-Ipson with p = 2 recovers a and v_bl and a may be held") {
  // a = 0.9 and v_bl = 133.8 m/s (seed 003 Table 6, T4) with p = 2; 110-330 m/s every 10 m/s; noise 2 m/s.
  auto data = generate(0.9, 2.0, 133.8, range(110, 330, 10), 2.0, 777);
  const auto fit = fitResidualVelocity(data, withModel(ResidualVelocityModel::rechtIpson));
  REQUIRE(fit.a.standardError);
  REQUIRE(fit.ballisticLimit.standardError);
  CHECK(fit.nFree == 2);
  CHECK(std::abs(fit.a.value - 0.9) < 3.0 * *fit.a.standardError);
  CHECK(std::abs(fit.ballisticLimit.value - 133.8) < 3.0 * *fit.ballisticLimit.standardError);

  // a held at m_p / (m_p + m_pl): only v_bl is fitted.
  const double a = rechtIpsonA(0.0197, 0.0049);
  auto held = generate(a, 2.0, 150.0, range(120, 330, 15), 2.0, 778);
  const auto heldFit = fitResidualVelocity(held, {.model = ResidualVelocityModel::rechtIpson, .fixedA = a});
  CHECK(heldFit.nFree == 1);
  CHECK(heldFit.a.status == ParameterStatus::fixed);
  CHECK(heldFit.a.value == a);
  CHECK_FALSE(heldFit.a.standardError);
  REQUIRE(heldFit.ballisticLimit.standardError);
  CHECK(std::abs(heldFit.ballisticLimit.value - 150.0) < 3.0 * *heldFit.ballisticLimit.standardError);
}

TEST_CASE("residual velocity: stopped shots hold v_bl above them") {
  // Exact data from v_bl = 300 m/s, perforating from 350 m/s. Alone they give v_bl = 300 m/s; a stopped
  // shot at 330 m/s makes that impossible, so v_bl must end on 330 m/s, with no standard error.
  auto data = generate(0.85, 2.3, 300.0, range(350, 800, 50));
  const auto free = fitResidualVelocity(data);
  CHECK(free.ballisticLimit.value == relApprox(300.0, 1e-6));
  data.shots.push_back({330.0, 0.0, 0});
  const auto held = fitResidualVelocity(data);
  CHECK(held.ballisticLimit.value == relApprox(330.0, 1e-12));
  CHECK(held.ballisticLimit.status == ParameterStatus::atBound);
  CHECK_FALSE(held.ballisticLimit.standardError);
  CHECK(held.ballisticLimit.note.find("stopped") != std::string::npos);
  CHECK(held.misclassified == 0);
  CHECK(held.ballisticLimitLower == 330.0);
  // a and p keep standard errors, conditional on v_bl held at its bound.
  CHECK(held.a.standardError);
  CHECK(held.p.standardError);
  // Every perforating row still lies above v_bl.
  for (const auto& s : data.shots)
    if (s.residualVelocity > 0.0) CHECK(s.impactVelocity > held.ballisticLimit.value);
}

TEST_CASE("residual velocity: overlapping outcomes give the least-squares optimum of the piecewise model") {
  // Seed 003 Table 8 (T8) constants, a stopped shot at 262 m/s above a perforating one at 250 m/s.
  const auto data =
      readVelocityData(std::string(BLT_DATA_DIR) + "/examples/residual_velocity_t8_overlap_synthetic.csv");
  const auto fit = fitResidualVelocity(data);
  CHECK(fit.outcomesOverlap);
  // Independent brute force over p (step 0.01) and v_bl (step 0.1 m/s) with a from linear least squares:
  // the fit must be at least as good as every grid point.
  const double grid = gridMinimumSsr(data, 1.0, 5.0, 200.0, 450.0);
  MESSAGE("overlap fit SSR ", fit.sumOfSquares, " grid minimum ", grid);
  CHECK(fit.sumOfSquares <= grid * (1.0 + 1e-9));
  // Misclassified shots counted by hand against the fitted v_bl.
  int wrong = 0;
  for (const auto& s : data.shots)
    if ((s.residualVelocity == 0.0) == (s.impactVelocity > fit.ballisticLimit.value)) ++wrong;
  CHECK(fit.misclassified == wrong);
  CHECK(fit.misclassified >= 1);
  // SSR and RMS agree with the model evaluated by hand.
  double ssr = 0.0;
  for (const auto& s : data.shots) {
    const double r =
        modelByHand(fit.a.value, fit.p.value, fit.ballisticLimit.value, s.impactVelocity) - s.residualVelocity;
    ssr += r * r;
  }
  CHECK(fit.sumOfSquares == relApprox(ssr, 1e-9));
  CHECK(fit.rms == relApprox(std::sqrt(ssr / fit.nUsed), 1e-9));
}

TEST_CASE("residual velocity: the example file recovers the constants it was made from") {
  // data/examples/residual_velocity_t4_synthetic.csv: seed 003 Table 6 T4 constants (a = 0.9, p = 2.6,
  // v_bl = 133.8 m/s) with 2 m/s noise (recipe in the file). Not a comparison with measurements.
  const auto data = readVelocityData(std::string(BLT_DATA_DIR) + "/examples/residual_velocity_t4_synthetic.csv");
  const auto fit = fitResidualVelocity(data);
  REQUIRE(fit.a.standardError);
  REQUIRE(fit.p.standardError);
  REQUIRE(fit.ballisticLimit.standardError);
  CHECK(std::abs(fit.a.value - 0.9) < 3.0 * *fit.a.standardError);
  CHECK(std::abs(fit.p.value - 2.6) < 3.0 * *fit.p.standardError);
  CHECK(std::abs(fit.ballisticLimit.value - 133.8) < 3.0 * *fit.ballisticLimit.standardError);
  CHECK(fit.nPoints == 13);
  CHECK(fit.nStopped == 3);
}

TEST_CASE("residual velocity: degenerate data give no standard errors and say why") {
  // Exactly as many perforating rows as free parameters: an exact fit, no degrees of freedom left.
  auto three = generate(0.85, 2.3, 300.0, {250, 400, 600, 800});
  const auto exact = fitResidualVelocity(three);
  CHECK(exact.dof == 0);
  CHECK_FALSE(exact.sigma);
  CHECK_FALSE(exact.a.standardError);
  CHECK(exact.covarianceNote.find("no residual degrees of freedom") != std::string::npos);
  // All perforating shots at one velocity: a, p and v_bl cannot be told apart.
  VelocityData same{"same", {{500, 300, 0}, {500, 302, 0}, {500, 298, 0}, {500, 301, 0}}};
  const auto degenerate = fitResidualVelocity(same);
  CHECK_FALSE(degenerate.ballisticLimit.standardError);
  CHECK(!degenerate.covarianceNote.empty());
}

TEST_CASE("residual velocity: bad data files give errors naming file and line and field and what is allowed") {
  auto parse = [](const std::string& text) { return velocityDataFromTable(csv::Table::parse(text, "rv.csv")); };
  CHECK_THROWS_WITH_AS(parse("impact_velocity_m_s,vr\n200,100\n"),
                       doctest::Contains("file rv.csv, field 'residual_velocity_m_s': the required column is missing"),
                       InputError);
  CHECK_THROWS_WITH_AS(parse(""), doctest::Contains("rv.csv: the file is empty"), InputError);
  CHECK_THROWS_WITH_AS(
      parse("impact_velocity_m_s,residual_velocity_m_s\n200,100\n-150,0\n"),
      doctest::Contains("file rv.csv, line 3, field 'impact_velocity_m_s': impact velocity -150 m/s is not positive "
                        "(allowed: an impact velocity above 0 m/s)"),
      InputError);
  CHECK_THROWS_WITH_AS(parse("impact_velocity_m_s,residual_velocity_m_s\n200,-4\n"),
                       doctest::Contains("line 2, field 'residual_velocity_m_s': residual velocity -4 m/s is negative"),
                       InputError);
  CHECK_THROWS_WITH_AS(parse("impact_velocity_m_s,residual_velocity_m_s\n200,210\n"),
                       doctest::Contains("residual velocity 210 m/s exceeds the impact velocity 200 m/s (allowed: 0 <= "
                                         "residual velocity <= impact velocity)"),
                       InputError);
  CHECK_THROWS_WITH_AS(parse("impact_velocity_m_s,residual_velocity_m_s\n200,fast\n"),
                       doctest::Contains("line 2, field 'residual_velocity_m_s': 'fast' is not a number"), InputError);
  const auto two = parse("impact_velocity_m_s,residual_velocity_m_s\n100,0\n200,100\n300,250\n");
  CHECK_THROWS_WITH_AS(fitResidualVelocity(two),
                       doctest::Contains("file rv.csv, field 'residual_velocity_m_s': 2 row(s) perforate (residual "
                                         "velocity > 0) but the lambert-jonas fit has 3 free parameters (allowed: at "
                                         "least 3 perforating rows"),
                       InputError);
  // The same two rows suffice for Recht-Ipson (a and v_bl).
  CHECK(fitResidualVelocity(two, withModel(ResidualVelocityModel::rechtIpson)).nFree == 2);
}
