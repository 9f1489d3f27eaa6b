// The streaming commands' shared reconstruction options (stream_options.hpp).
#include "stream_options.hpp"

#include "aosr/core/error.hpp"
#include "cli_util.hpp"

namespace aosr::cli {

void AddStreamOptions(CLI::App* cmd, StreamArgs* a) {
  cmd->add_option("-m,--method", a->method, "tikhonov | linear | tv")
      ->capture_default_str()
      ->check(CLI::IsMember({"tikhonov", "linear", "tv"}));
  cmd->add_option("--window", a->window, "sliding | cycle")->capture_default_str()->check(CLI::IsMember({"sliding", "cycle"}));
  cmd->add_option("--weights", a->weights, "auto | background | dataset | mask (as aosr reconstruct)")->capture_default_str();
  cmd->add_option("--lambda", a->lambda, "Tikhonov lambda (default: the --lambda-rule on the first window, then fixed)")
      ->check(NonNegativeFinite());
  cmd->add_option("--lambda-rule", a->lambda_rule, "gcv | discrepancy | lcurve | upre (run once, on the first window)")
      ->capture_default_str();
  cmd->add_option("--prior", a->prior, "Tikhonov prior: gradient | laplacian | identity | power-spectrum")->capture_default_str();
  cmd->add_option("--target-psf", a->target_psf, "linear: auto | gaussian:<FWHM in HR px>")->capture_default_str();
  cmd->add_option("--leakage", a->leakage, "linear: leakage bound epsilon")->capture_default_str();
  cmd->add_option("--mu", a->mu, "tv: weight mu (default: automatic, on the first window)")->check(NonNegativeFinite());
  cmd->add_option("--tv-iterations", a->tv_iterations, "tv: ADMM iterations per warm-started output")
      ->capture_default_str()
      ->check(CLI::Range(1, 100000));
  cmd->add_option("--tv-first-iterations", a->tv_first_iterations, "tv: ADMM iteration limit of the first window")
      ->capture_default_str()
      ->check(CLI::Range(1, 1000000));
  cmd->add_flag("--batch", a->batch, "the batch solver on every window instead of the slot filter (to compare)");
}

VideoOptions StreamVideoOptions(const StreamArgs& a, const char* command) {
  VideoOptions vo;
  vo.method = ParseReconstructionMethod(a.method);
  vo.window = ParseVideoWindow(a.window);
  vo.tv_iterations = a.tv_iterations;
  vo.slot_filter = !a.batch;
  // As `aosr reconstruct`: weights are inverse variances, so a weight-1 pixel has sigma 1 (the discrepancy rule).
  vo.reconstruct.tikhonov.noise_sigma = 1.0;
  vo.reconstruct.linear.noise_sigma = 1.0;
  vo.reconstruct.tikhonov.prior = ParseTikhonovPrior(a.prior);
  if (a.lambda >= 0) {
    vo.reconstruct.tikhonov.lambda_rule = TikhonovLambdaRule::kFixed;
    vo.reconstruct.tikhonov.lambda = a.lambda;
  } else {
    vo.reconstruct.tikhonov.lambda_rule = ParseTikhonovLambdaRule(a.lambda_rule);
  }
  if (a.target_psf.rfind("gaussian:", 0) == 0) {
    vo.reconstruct.linear.kind = TargetPsfKind::kGaussian;
    try {
      vo.reconstruct.linear.fwhm_hr_px = std::stod(a.target_psf.substr(9));
    } catch (const std::exception&) {
      throw InvalidArgument(command, "--target-psf", a.target_psf, "auto | gaussian:<FWHM in HR px>");
    }
  } else if (a.target_psf != "auto") {
    throw InvalidArgument(command, "--target-psf", a.target_psf, "auto | gaussian:<FWHM in HR px>");
  }
  vo.reconstruct.linear.leakage = a.leakage;
  if (a.mu >= 0) {
    vo.reconstruct.auto_regularisation = false;
    vo.reconstruct.tv.mu = a.mu;
  }
  vo.reconstruct.tv.max_iterations = a.tv_first_iterations;
  std::string why;
  if (!vo.IsValid(&why)) throw InvalidArgument(std::string(command) + ": " + why);
  return vo;
}

DatasetProblemOptions StreamProblemOptions(const StreamArgs& a) {
  DatasetProblemOptions po;
  po.weights = ParseDatasetWeights(a.weights);
  return po;
}

}  // namespace aosr::cli
