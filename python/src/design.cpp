// Bindings of the design layer: aosr.design(scene, ...), the phase-design study of `aosr design`
// (design/design_study.hpp: the same library call), with the CLI's options as keyword arguments.
#include "aosr/calib/calibration_file.hpp"
#include "aosr/core/error.hpp"
#include "aosr/design/design_file.hpp"
#include "aosr/design/design_study.hpp"
#include "aosr/scene/scene_spec.hpp"
#include "bindings.hpp"
#include "common.hpp"

namespace aosr::python {

void BindDesign(py::module_& m) {
  m.def(
      "design",
      [](py::object scene, py::object output, py::object calibration, const std::string& param, int modes,
         double rms_max, double strehl_min, int starts, int realisations, int screens, double lambda_,
         const std::string& prior, int iterations, int threads, std::uint64_t seed, const std::string& objective,
         const std::string& loss, int training_scenes, std::vector<std::string> training, double training_zoom,
         double noise_sigma, int validation_realisations, double map_lambda, double epsilon,
         const std::string& map_prior, double min_gain, int sky_oversampling, py::object progress) {
        DesignStudyOptions o;
        o.param = param;
        o.modes = modes;
        o.rms_max_nm = rms_max;
        o.strehl_min = strehl_min;
        o.starts = starts;
        o.realisations = realisations;
        o.screens = screens;
        o.lambda = lambda_;
        o.prior = prior;
        o.iterations = iterations;
        o.threads = threads;
        o.seed = seed;
        o.objective = objective;
        o.loss = loss;
        o.training_scenes = training_scenes;
        o.training = std::move(training);
        o.training_zoom = training_zoom;
        o.noise_sigma = noise_sigma;
        o.validation_realisations = validation_realisations;
        o.map_lambda = map_lambda;
        o.epsilon = epsilon;
        o.map_prior = map_prior;
        o.min_gain_db = min_gain;
        o.sky_oversampling = sky_oversampling;
        // The CLI's range checks (its CLI11 validators), so that both refuse the same values.
        CheckArgument(param == "raster" || param == "tiptilt" || param == "zernike" || param == "actuators", "aosr.design",
                      "param", param, "raster | tiptilt | zernike | actuators");
        CheckArgument(modes >= 2 && modes <= 200, "aosr.design", "modes", modes, "2..200");
        CheckArgument(starts >= 1 && starts <= 64, "aosr.design", "starts", starts, "1..64");
        CheckArgument(realisations >= 0 && realisations <= 64, "aosr.design", "realisations", realisations, "0..64");
        CheckArgument(screens >= 1 && screens <= 256, "aosr.design", "screens", screens, "1..256");
        CheckArgument(iterations >= 1, "aosr.design", "iterations", iterations, ">= 1");
        CheckArgument(threads >= 1 && threads <= 64, "aosr.design", "threads", threads, "1..64");
        CheckArgument(objective == "A" || objective == "B", "aosr.design", "objective", objective, "A | B");
        CheckArgument(rms_max >= 0, "aosr.design", "rms_max", rms_max, ">= 0 nm (0: none)");
        CheckArgument(strehl_min >= 0 && strehl_min < 1, "aosr.design", "strehl_min", strehl_min, "[0, 1)");
        CheckArgument(lambda_ > 0, "aosr.design", "lambda_", lambda_, "> 0");
        std::shared_ptr<const SceneSpec> spec;
        if (py::hasattr(scene, "_spec_json")) {
          const py::tuple t = scene.attr("_spec_json")();
          spec = std::make_shared<const SceneSpec>(ParseScene(ToJson(t[0]), t[1].cast<std::string>()));
        } else {
          const std::string path = PathString(scene);
          spec = std::make_shared<const SceneSpec>(WithoutGil([&] { return LoadScene(path); }));
        }
        const std::string out = output.is_none() ? std::string() : PathString(output);
        const std::string cal = calibration.is_none() ? std::string() : PathString(calibration);
        PythonProgress poll(progress);
        o.progress = poll.Callback();
        DesignStudy study = WithoutGil([&] {
          DesignStudy s = RunDesignStudy(*spec, o);
          if (s.result.summary.termination == Termination::kUserCancelled) return s;  // nothing written
          if (!cal.empty()) ApplyCalibrationToDesignFile(cal, s.result.offsets, &s.file);
          if (!out.empty()) WriteDesignFile(out, s.file);
          return s;
        });
        poll.RaiseIfPending();  // Ctrl-C (KeyboardInterrupt) or the progress callable's exception
        nlohmann::json j = study.summary;
        const bool cancelled = study.result.summary.termination == Termination::kUserCancelled;
        j["output"] = out.empty() || cancelled ? nlohmann::json() : nlohmann::json(out);
        j["design"] = study.file;
        return FromJson(j);
      },
      py::arg("scene"), py::kw_only(), py::arg("output") = py::none(), py::arg("calibration") = py::none(),
      py::arg("param") = "zernike", py::arg("modes") = 20, py::arg("rms_max") = 0.0, py::arg("strehl_min") = 0.0,
      py::arg("starts") = 3, py::arg("realisations") = 2, py::arg("screens") = 4, py::arg("lambda_") = 1e-2,
      py::arg("prior") = "gradient", py::arg("iterations") = 100, py::arg("threads") = 2, py::arg("seed") = 1,
      py::arg("objective") = "A", py::arg("loss") = "l1", py::arg("training_scenes") = 3,
      py::arg("training") = std::vector<std::string>(), py::arg("training_zoom") = 1.0, py::arg("noise_sigma") = 0.04,
      py::arg("validation_realisations") = 4, py::arg("map_lambda") = -1.0, py::arg("epsilon") = 1e-3,
      py::arg("map_prior") = "charbonnier-tv", py::arg("min_gain") = 0.2, py::arg("sky_oversampling") = 4, py::arg("progress") = py::none(),
      R"doc(Designs the N per-exposure DM offsets of a scene, as `aosr design SCENE` (include/aosr/design/design_study.hpp).

scene       a scene path or aosr.Scene (its telescope, AO, camera, r and N)
output      also write the design file (scenes load it with "offsets": {"type": "design", "file": ...})
calibration a calibration.json: the file's frames become the commands for the calibrated DM
param, modes, rms_max [nm], strehl_min, starts, realisations, screens, lambda_, prior, iterations, threads,
seed, objective ('A' | 'B'), loss, training_scenes, training (image paths), training_zoom, noise_sigma,
validation_realisations, map_lambda (< 0: automatic), epsilon, map_prior, min_gain [dB], sky_oversampling: the CLI's
options of the same names.
progress    optional callable(dict) called during the optimisation (stage 'design', iteration = L-BFGS iterations
            over all starts, total = starts x iterations, value = J); returning False stops it: the best design
            so far is returned with its termination 'cancelled', unvalidated, and no file is written.
Returns the dict `aosr design --json` prints (without total_seconds); its "design" is the design file, its "gain"
the expected gain over the raster ("db", "stderr_db", "advice": "design" | "raster", "reason"; with objective A
judged on a sky sky_oversampling times finer than the HR grid, "hr_grid_sky" holds the HR grid's own figure).
The GIL is released; Ctrl-C stops the optimisation after the current iteration and raises KeyboardInterrupt.)doc");
}

}  // namespace aosr::python
