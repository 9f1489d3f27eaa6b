// aosr: super-resolved imaging with adaptive optics. Entry point of the command-line tool.
//
// Exit codes: 0 success, 1 a usage or input error (the message names what is wrong), 2 an internal error.
#include <cstdio>
#include <exception>
#include <new>

#include "aosr/core/error.hpp"
#include "aosr/core/memory.hpp"
#include "cli_util.hpp"
#include "commands.hpp"

int main(int argc, char** argv) {
  aosr::TuneAllocatorForLargeArrays();  // freed image-sized arrays reused, not page-faulted in again (memory.hpp)
  CLI::App app{
      "aosr: super-resolved imaging with adaptive optics.\n"
      "The DM adds a designed phase to each of N sub-exposures; reconstructing the N undersampled frames\n"
      "jointly gives an image r times finer than the camera's pixels."};
  // A fixed name (not argv[0]): the help reads "Usage: aosr ...", however the program was started (the launcher,
  // src/cli/launcher/launcher.cpp, serves the same text from build time).
  app.name("aosr");
  app.set_version_flag("--version", std::string("aosr ") + AOSR_VERSION);
  app.require_subcommand(1);
  aosr::cli::RegisterDemo(app);
  aosr::cli::RegisterPsf(app);
  aosr::cli::RegisterSimulate(app);
  aosr::cli::RegisterEvaluate(app);
  aosr::cli::RegisterDesign(app);
  aosr::cli::RegisterCalibrate(app);
  aosr::cli::RegisterReconstruct(app);
  aosr::cli::RegisterTradeoff(app);
  aosr::cli::RegisterMtf(app);
  aosr::cli::RegisterVideo(app);
  aosr::cli::RegisterWatch(app);
  aosr::cli::SetCommandLine(argc, argv);
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    // CLI11 prints the message (or the help/version text) and returns its own code per kind of error
    // (105 for a failed validator, 106 for a missing option, ...); the documented contract is 1 for any
    // usage error, so scripts need not know CLI11's numbering.
    return app.exit(e) == 0 ? 0 : 1;
  } catch (const aosr::InvalidArgument& e) {
    std::fprintf(stderr, "aosr: error: %s\n", e.what());
    return 1;
  } catch (const aosr::IoError& e) {
    std::fprintf(stderr, "aosr: error: %s\n", e.what());
    return 1;
  } catch (const aosr::ResourceError& e) {
    std::fprintf(stderr, "aosr: error: %s\n", e.what());
    return 1;
  } catch (const std::bad_alloc&) {
    // Requests are checked against memory.hpp's estimates before allocating; reaching this means an estimate
    // missed something, which is our bug, not the user's.
    std::fprintf(stderr, "aosr: internal error: out of memory (std::bad_alloc) although the request passed the "
                         "memory check; set AOSR_MEMORY_LIMIT lower or report this\n");
    return 2;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "aosr: internal error: %s\n", e.what());
    return 2;
  }
  return 0;
}
