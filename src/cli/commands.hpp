// Registration of the `aosr` subcommands. Each Register* adds its subcommand with options and a
// callback to `app`; main() only parses and maps exceptions to exit codes.
#pragma once

#include <CLI/CLI.hpp>

namespace aosr::cli {

void RegisterDemo(CLI::App& app);
void RegisterPsf(CLI::App& app);
void RegisterSimulate(CLI::App& app);
void RegisterEvaluate(CLI::App& app);
void RegisterDesign(CLI::App& app);
void RegisterCalibrate(CLI::App& app);
void RegisterReconstruct(CLI::App& app);
void RegisterTradeoff(CLI::App& app);
void RegisterMtf(CLI::App& app);
void RegisterVideo(CLI::App& app);
void RegisterWatch(CLI::App& app);

}  // namespace aosr::cli
