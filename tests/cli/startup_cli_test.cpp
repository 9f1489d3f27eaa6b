// The `aosr` launcher (src/cli/launcher/launcher.cpp) against the program it runs (libexec/aosr/aosr-engine):
// --version, --help and every COMMAND --help answered by the launcher alone are the engine's own bytes and
// exit status, and everything else reaches the engine unchanged (arguments, exit codes, stderr). Start-up
// time is not asserted here (tests never assert wall time): README.md, "Start-up", has the measurement and
// its command.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>
#include <sstream>
#include <string>
#include <vector>

#include "support/testing.hpp"

namespace AOSR_TEST_NS {

namespace fs = std::filesystem;
using aosr::test::CliRun;
using aosr::test::RunCli;
using aosr::test::RunShell;
using ::testing::HasSubstr;
using ::testing::Not;

std::string Engine() {
  return (fs::path(AOSR_CLI_PATH).parent_path() / "libexec" / "aosr" / "aosr-engine").string();
}

CliRun RunEngine(const std::string& args) { return RunShell(Engine() + " " + args); }

// The commands the top-level help lists (CLI11: the indented names under "Subcommands:").
std::vector<std::string> Commands(const std::string& help) {
  std::vector<std::string> out;
  std::istringstream in(help.substr(help.find("Subcommands:")));
  std::string line;
  std::getline(in, line);
  while (std::getline(in, line) && line.rfind("  ", 0) == 0) {
    std::istringstream words(line);
    std::string name;
    words >> name;
    out.push_back(name);
  }
  return out;
}

TEST(StartupCliTest, VersionAndTopLevelHelpAreTheEnginesOwn) {
  ASSERT_TRUE(fs::exists(Engine())) << Engine();
  const CliRun v = RunCli("--version");
  EXPECT_EQ(v.status, 0);
  EXPECT_THAT(v.out, HasSubstr("aosr "));
  const CliRun ev = RunEngine("--version");
  EXPECT_EQ(v.out, ev.out);
  for (const char* flag : {"--help", "-h"}) {
    const CliRun h = RunCli(flag), eh = RunEngine(flag);
    EXPECT_EQ(h.status, 0) << flag;
    EXPECT_EQ(h.status, eh.status) << flag;
    EXPECT_EQ(h.out, eh.out) << flag;
    EXPECT_THAT(h.out, HasSubstr("Usage: aosr"));
  }
}

TEST(StartupCliTest, EveryCommandHelpIsTheEnginesOwn) {
  const std::vector<std::string> commands = Commands(RunEngine("--help").out);
  // The nine commands of README.md at least (a new command is picked up by the generator on its own).
  for (const char* c :
       {"demo", "psf", "simulate", "evaluate", "design", "calibrate", "reconstruct", "tradeoff", "mtf"})
    EXPECT_NE(std::find(commands.begin(), commands.end(), c), commands.end()) << c;
  for (const std::string& c : commands) {
    for (const char* flag : {"--help", "-h"}) {
      const CliRun h = RunCli(c + " " + flag), eh = RunEngine(c + " " + flag);
      EXPECT_EQ(h.status, 0) << c << " " << flag << ": " << h.out;
      EXPECT_EQ(h.out, eh.out) << c << " " << flag;
      EXPECT_THAT(h.out, HasSubstr("Usage: aosr " + c)) << c;
    }
  }
}

TEST(StartupCliTest, EverythingElseReachesTheEngine) {
  // Errors: the same message and exit status as the engine's.
  for (const char* args :
       {"", "no-such-command", "--version --help", "evaluate --truth /nonexistent.fits --estimate x.fits",
        "reconstruct --method", "demo --help --json"}) {
    const CliRun r = RunCli(args), e = RunEngine(args);
    EXPECT_EQ(r.status, e.status) << "'" << args << "'";
    EXPECT_EQ(r.out, e.out) << "'" << args << "'";
  }
  // A real command runs (psf is quick) and its output is the engine's.
  const CliRun r = RunCli("psf paper-8m --mode diffraction --size 32 --json");
  ASSERT_EQ(r.status, 0) << r.out;
  EXPECT_THAT(r.out, HasSubstr("strehl"));
}

TEST(StartupCliTest, AMissingEngineIsACleanError) {
  const CliRun r = RunShell("AOSR_ENGINE=/nonexistent/aosr-engine " + std::string(AOSR_CLI_PATH) + " demo");
  EXPECT_EQ(r.status, 2);
  EXPECT_THAT(r.out, HasSubstr("cannot run /nonexistent/aosr-engine"));
  // The fast paths need no engine at all.
  const CliRun v =
      RunShell("AOSR_ENGINE=/nonexistent/aosr-engine " + std::string(AOSR_CLI_PATH) + " --version");
  EXPECT_EQ(v.status, 0);
}

// The engine starts with glibc's malloc tunables (launcher.cpp: the thresholds and transparent huge pages), unless
// the user chose malloc settings or opted out. /usr/bin/env as the engine prints what it was given.
TEST(StartupCliTest, TheEngineGetsTheAllocatorTunablesUnlessTheUserChoseOthers) {
  const std::string launch = "env -u GLIBC_TUNABLES -u MALLOC_TRIM_THRESHOLD_ -u MALLOC_MMAP_THRESHOLD_ -u "
                             "MALLOC_TOP_PAD_ -u AOSR_MALLOC_TUNING AOSR_ENGINE=/usr/bin/env ";
  const std::string cli = std::string(AOSR_CLI_PATH);
  const CliRun plain = RunShell(launch + cli);
  ASSERT_EQ(plain.status, 0) << plain.out;
  EXPECT_THAT(plain.out, HasSubstr("GLIBC_TUNABLES=glibc.malloc.hugetlb=1:glibc.malloc.mmap_threshold=33554432:"
                                   "glibc.malloc.trim_threshold=1073741824:glibc.malloc.mmap_max=0\n"));
  // Other tunables are kept, ours appended.
  EXPECT_THAT(RunShell(launch + "GLIBC_TUNABLES=glibc.rtld.nns=4 " + cli).out,
              HasSubstr("GLIBC_TUNABLES=glibc.rtld.nns=4:glibc.malloc.hugetlb=1:"));
  for (const std::string user : {"GLIBC_TUNABLES=glibc.malloc.arena_max=2", "MALLOC_TRIM_THRESHOLD_=65536",
                                 "AOSR_MALLOC_TUNING=0"}) {
    const CliRun r = RunShell(launch + user + " " + cli);
    EXPECT_THAT(r.out, Not(HasSubstr("hugetlb"))) << user;
  }
}

}  // namespace
