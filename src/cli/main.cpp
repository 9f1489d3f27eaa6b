// aosr command-line entry point (placeholder replaced by the CLI commands as they land).
#include <CLI/CLI.hpp>

int main(int argc, char** argv) {
  CLI::App app{"aosr: super-resolved imaging with adaptive optics"};
  app.require_subcommand(0, 1);
  CLI11_PARSE(app, argc, argv);
  return 0;
}
