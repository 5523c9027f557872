#pragma once
// Each subcommand lives in its own file and registers itself on its parent here.
#include <CLI/CLI.hpp>

namespace blt::cli {
void registerLaminateCommand(CLI::App& analytic);          // analytic_laminate.cpp
void registerResidualVelocityCommand(CLI::App& analytic);  // analytic_residual_velocity.cpp
void registerChenLiCommand(CLI::App& analytic);            // analytic_chen_li.cpp
void registerFlorenceCommand(CLI::App& analytic);          // analytic_florence.cpp
void registerUnitsCommand(CLI::App& app);                  // units.cpp
void registerMaterialsCommand(CLI::App& app);              // materials.cpp
void registerBleCommand(CLI::App& app);                    // ble.cpp
void registerSimCommand(CLI::App& app);                    // sim.cpp
void registerSimScenarioCommands(CLI::App& sim);          // sim_scenario.cpp: sim run, sim bisect
void registerBenchCommand(CLI::App& app);                  // sim.cpp
void registerBenchScenarioCommand(CLI::App& bench);        // sim_scenario.cpp: bench scenario
void registerValidateCommand(CLI::App& app);               // validate.cpp
void registerCalibrateCommand(CLI::App& app);              // calibrate.cpp
void registerBenchCalibrateCommand(CLI::App& bench);       // calibrate.cpp: bench calibrate
void registerCampaignCommand(CLI::App& app);               // campaign.cpp
void registerBenchCampaignCommand(CLI::App& bench);        // campaign.cpp: bench campaign
}  // namespace blt::cli
