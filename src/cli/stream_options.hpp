// The reconstruction options of the streaming commands (`aosr video`, `aosr watch`): one definition, so that a
// movie made afterwards and the quick-look seen at the telescope are the same reconstruction.
#pragma once

#include <CLI/CLI.hpp>
#include <string>

#include "aosr/solvers/dataset_problem.hpp"
#include "aosr/solvers/video_stream.hpp"

namespace aosr::cli {

struct StreamArgs {
  std::string method = "tikhonov";
  std::string window = "sliding";
  std::string weights = "auto";
  double lambda = -1;
  std::string lambda_rule = "gcv";
  std::string prior = "gradient";
  std::string target_psf = "auto";
  double leakage = 1e-3;
  double mu = -1;
  int tv_iterations = 10;
  int tv_first_iterations = 1000;
  bool batch = false;
};

void AddStreamOptions(CLI::App* cmd, StreamArgs* a);
// The options as the library takes them; InvalidArgument naming `command` and the option for a bad value.
VideoOptions StreamVideoOptions(const StreamArgs& a, const char* command);
DatasetProblemOptions StreamProblemOptions(const StreamArgs& a);

}  // namespace aosr::cli
