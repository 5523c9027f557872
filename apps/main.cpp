// blt: the ballistic-limit design toolkit's one command-line tool.
#include <iostream>

#include "blt/core/error.hpp"
#include "commands.hpp"

int main(int argc, char** argv) {
  CLI::App app{
      "blt: ballistic-limit design toolkit.\n"
      "Values take explicit units (1.2 mm, 6.5 km/s, 45 deg, 2770 kg/m3, 490 MPa); SI is used inside.\n"
      "Every subcommand accepts --json for machine-readable output."};
  app.set_version_flag("--version", BLT_VERSION);
  app.require_subcommand(1);
  app.fallthrough();

  auto* analytic = app.add_subcommand(
      "analytic", "Analytical baselines: MLI laminate, residual velocity, Chen-Li, Florence");
  analytic->require_subcommand(1);
  blt::cli::registerLaminateCommand(*analytic);
  blt::cli::registerResidualVelocityCommand(*analytic);
  blt::cli::registerChenLiCommand(*analytic);
  blt::cli::registerFlorenceCommand(*analytic);
  blt::cli::registerMaterialsCommand(app);
  blt::cli::registerBleCommand(app);
  blt::cli::registerSimCommand(app);
  blt::cli::registerBenchCommand(app);
  blt::cli::registerBenchCampaignCommand(*app.get_subcommand("bench"));
  blt::cli::registerBenchCalibrateCommand(*app.get_subcommand("bench"));
  blt::cli::registerValidateCommand(app);
  blt::cli::registerCalibrateCommand(app);
  blt::cli::registerCampaignCommand(app);
  blt::cli::registerUnitsCommand(app);

  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return app.exit(e);
  } catch (const blt::InputError& e) {
    std::cerr << "blt: error: " << e.what() << "\n";
    return 2;
  } catch (const std::exception& e) {
    std::cerr << "blt: failed: " << e.what() << "\n";
    return 1;
  }
  return 0;
}
