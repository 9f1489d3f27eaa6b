// The C++ side of the Python round-trip tests and of bench/python_bench.py: the library calls the bindings
// make, with the CLI's defaults, results written as float64 FITS (bit-exact) and a JSON line of scalars.
//
//   aosr_py_reference reconstruct DATASET METHOD OUT.fits [--iterations N] [--repeat K]
//     = aosr.reconstruct(DATASET, METHOD[, iterations=N]): ProblemFromDataset + Reconstruct. Prints
//     {"regularisation", "iterations", "termination", "seconds"} with seconds the best of K timed runs of the
//     whole call (dataset already loaded), the figure the bench compares with Python's.
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstring>
#include <string>
#include <thread>

#include "aosr/core/error.hpp"
#include "aosr/core/parallel.hpp"
#include "aosr/io/fits.hpp"
#include "aosr/scene/dataset.hpp"
#include "aosr/solvers/dataset_problem.hpp"
#include "aosr/solvers/reconstruct.hpp"

int main(int argc, char** argv) {
  using namespace aosr;
  try {
    if (argc < 5 || std::strcmp(argv[1], "reconstruct") != 0) {
      std::fprintf(stderr, "usage: %s reconstruct DATASET METHOD OUT.fits [--iterations N] [--repeat K]\n", argv[0]);
      return 2;
    }
    int iterations = -1, repeat = 1;
    for (int i = 5; i + 1 < argc; i += 2) {
      if (std::strcmp(argv[i], "--iterations") == 0) iterations = std::stoi(argv[i + 1]);
      else if (std::strcmp(argv[i], "--repeat") == 0) repeat = std::max(1, std::stoi(argv[i + 1]));
      else throw InvalidArgument(std::string("unknown option ") + argv[i]);
    }
    // The CLI's defaults (src/cli/reconstruct_command.cpp), which aosr.reconstruct uses too.
    ReconstructOptions o;
    o.method = ParseReconstructionMethod(argv[3]);
    o.tikhonov.noise_sigma = 1.0;
    o.linear.noise_sigma = 1.0;
    o.drizzle.compute_context = false;
    if (iterations > 0) o.tv.max_iterations = o.map.max_iterations = iterations;
    // As the CLI and `import aosr`: every hardware thread.
    SetDefaultThreads(std::min(int(std::max(1u, std::thread::hardware_concurrency())), 256));
    const Dataset d = LoadDataset(argv[2]);
    Reconstruction rec;
    double best = 1e300;
    for (int k = 0; k < repeat; ++k) {
      const auto t0 = std::chrono::steady_clock::now();
      DatasetProblemOptions dpo;
      dpo.method = o.method;  // --weights auto resolves per method, as the CLI and Python do
      const DatasetProblem dp = ProblemFromDataset(d, dpo);
      rec = Reconstruct(dp.problem, o);
      best = std::min(best, std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count());
    }
    WriteFits(argv[4], rec.image, {}, FitsType::kFloat64);
    if (!rec.aux_name.empty()) WriteFits(std::string(argv[4]) + ".aux.fits", rec.aux, {}, FitsType::kFloat64);
    std::printf("{\"regularisation\": %.17g, \"iterations\": %d, \"termination\": \"%s\", \"seconds\": %.6f}\n",
                rec.regularisation, rec.summary.iterations, ToString(rec.summary.termination), best);
    return 0;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "%s\n", e.what());
    return 1;
  }
}
