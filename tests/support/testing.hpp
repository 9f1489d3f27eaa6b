// Helpers shared by aosr's tests (header-only; include as "support/testing.hpp").
#pragma once

#include <sys/wait.h>

#include <cstdint>
#include <cstdio>
#include <exception>
#include <random>
#include <string>
#include <thread>
#include <utility>

#include "aosr/core/error.hpp"
#include "aosr/core/image.hpp"

// AOSR_TEST_ASAN / AOSR_TEST_TSAN: 1 in an AddressSanitizer / ThreadSanitizer build. GCC defines
// __SANITIZE_ADDRESS__; clang 14 (scripts/sanitize.sh's compiler) answers only through __has_feature.
#if defined(__SANITIZE_ADDRESS__)
#define AOSR_TEST_ASAN 1
#elif defined(__has_feature)
#if __has_feature(address_sanitizer)
#define AOSR_TEST_ASAN 1
#endif
#endif
#if defined(__SANITIZE_THREAD__)
#define AOSR_TEST_TSAN 1
#elif defined(__has_feature)
#if __has_feature(thread_sanitizer)
#define AOSR_TEST_TSAN 1
#endif
#endif

namespace aosr::test {

// Runs `f` and returns the message of the exception of type E it throws; "no exception" if none, and
// "wrong exception type: ..." for any other exception, so HasSubstr checks also pin the type.
template <typename E = InvalidArgument, typename F>
std::string ErrorOf(F&& f) {
  try {
    f();
  } catch (const E& e) {
    return e.what();
  } catch (const std::exception& e) {
    return std::string("wrong exception type: ") + e.what();
  }
  return "no exception";
}

// An image of independent N(0, 1) (normal = true) or U(0, 1) values from a fixed seed.
inline Image RandomImage(Shape s, std::uint64_t seed, bool normal = true) {
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> n01;
  std::uniform_real_distribution<double> u01;
  Image img(s.rows, s.cols);
  for (Index i = 0; i < img.size(); ++i) img.data()[i] = normal ? n01(rng) : u01(rng);
  return img;
}

// Runs the built `aosr` executable with `args` (stderr merged into the output).
struct CliRun {
  int status = -1;
  std::string out;
};

// Runs a shell command line (stderr merged into the output): for runs that need the shell, e.g. `ulimit`.
inline CliRun RunShell(const std::string& command) {
  CliRun run;
  FILE* p = popen((command + " 2>&1").c_str(), "r");
  if (!p) return run;
  char buf[4096];
  while (std::size_t n = fread(buf, 1, sizeof buf, p)) run.out.append(buf, n);
  const int status = pclose(p);
  run.status = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  return run;
}

// A thread joined when it goes out of scope, so that a failed ASSERT or an exception in the test body ends the
// test as a failure instead of std::terminate (a joinable std::thread's destructor).
class JoiningThread {
 public:
  template <typename F>
  explicit JoiningThread(F&& f) : t_(std::forward<F>(f)) {}
  ~JoiningThread() { Join(); }
  JoiningThread(const JoiningThread&) = delete;
  JoiningThread& operator=(const JoiningThread&) = delete;
  void Join() {
    if (t_.joinable()) t_.join();
  }

 private:
  std::thread t_;
};

#ifdef AOSR_CLI_PATH
inline CliRun RunCli(const std::string& args) { return RunShell(std::string(AOSR_CLI_PATH) + " " + args); }
#endif

}  // namespace aosr::test
