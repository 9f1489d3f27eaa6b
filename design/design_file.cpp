#include "aosr/design/design_file.hpp"

#include <algorithm>
#include <cmath>
#include <fstream>

#include "aosr/ao/shack_hartmann.hpp"
#include "aosr/core/error.hpp"
#include "aosr/design/design_empirical.hpp"
#include "aosr/design/design_objective.hpp"
#include "aosr/io/atomic_file.hpp"
#include "aosr/optics/deformable_mirror.hpp"
#include "aosr/optics/zernike.hpp"
#include "aosr/scene/pipeline.hpp"

namespace aosr {
namespace {

constexpr double kNm = 1e-9;

// The pupil grid the design file's sensor samples: the telescope's own when its lenslets divide it (with at
// least 2 pixels per lenslet), else the smallest multiple of the lenslet count above it. The reference slopes
// are a property of the offset's wavefront and the lenslet geometry, not of the grid the design was computed
// on: the paper bench's 25 lenslets do not divide its 128-pixel pupil grid (the grid its PSFs need), so its
// slopes are computed on 150 pixels (6 per lenslet) from the offsets' grid-free description (shifts, Zernike
// terms, actuator commands) rendered afresh there.
Index SensorPupilGrid(const SceneSpec& scene) {
  const Index n = scene.telescope.pupil_px;
  const Index m = scene.telescope.ao->wfs.lenslets_across;
  if (m >= 1 && n % m == 0 && n / m >= 2) return n;
  return m * std::max<Index>(2, (n + m - 1) / m);
}

std::unique_ptr<ShackHartmann> GeometricSensor(const SceneSpec& scene) {
  if (!scene.telescope.ao) return nullptr;
  TelescopePreset t = scene.telescope;
  t.pupil_px = SensorPupilGrid(scene);
  AoSystemSpec spec = t.ToAoSystemSpec(SensorKind::kGeometric, 0);
  ShackHartmannOptions o = spec.wfs;
  o.mode = ShackHartmannMode::kGeometric;
  o.noise = ShackHartmannNoise();  // noise-free: offsets are references, not measurements
  return std::make_unique<ShackHartmann>(spec.amplitude, spec.diameter_m, o);
}

// The offset's Zernike coefficients (Noll 1..kModalContentNoll, least squares over the pupil, weighted by its
// amplitude) and the pupil RMS of what they leave.
void ModalContent(const DesignPupil& pupil, const Image& opd, DesignFrameReport* r) {
  const Image& a = pupil.amplitude;
  r->zernike_m = ProjectOntoZernike(opd, a, kModalContentNoll);
  Image fit = Image::Zero(opd.rows(), opd.cols());
  for (int j = 1; j <= kModalContentNoll; ++j) fit += r->zernike_m[j - 1] * ZernikeUnmasked(j, opd.rows());
  const double w = a.sum();
  const Image rest = opd - fit;
  const double mean = (a * rest).sum() / w;
  r->beyond_m = std::sqrt(std::max(0.0, (a * (rest - mean).square()).sum() / w));
}

}  // namespace

std::vector<DesignFrameReport> DescribeDesign(const SceneSpec& scene, const DesignParameterisation& p,
                                              const std::vector<Image>& opds, const std::vector<DmOffset>& offsets) {
  const char* fn = "DescribeDesign";
  CheckArgument(int(opds.size()) == p.frames(), fn, "opds count", opds.size(), std::to_string(p.frames()));
  CheckArgument(offsets.size() == opds.size(), fn, "offsets count", offsets.size(),
                std::to_string(opds.size()) + " (one per OPD)");
  std::unique_ptr<ShackHartmann> sh = GeometricSensor(scene);
  // On a sensor grid other than the pupil grid the OPDs are rendered afresh from the offsets.
  SceneSpec resampled;
  std::unique_ptr<DeformableMirror> dm;
  const bool regrid = sh && SensorPupilGrid(scene) != scene.telescope.pupil_px;
  if (regrid) {
    resampled = scene;
    resampled.telescope.pupil_px = SensorPupilGrid(scene);
    dm = std::make_unique<DeformableMirror>(resampled.telescope.pupil_px, resampled.telescope.aperture.pupil,
                                            resampled.telescope.ao->dm);
  }
  std::vector<DesignFrameReport> out;
  for (std::size_t i = 0; i < opds.size(); ++i) {
    const Image& w = opds[i];
    CheckArgument(ShapeOf(w) == Shape{p.pupil_n(), p.pupil_n()}, fn, "opd shape", ToString(ShapeOf(w)),
                  "the pupil grid " + std::to_string(p.pupil_n()));
    DesignFrameReport r;
    r.rms_m = p.OpdRms(w);
    ModalContent(p.pupil(), w, &r);
    r.strehl = p.StrehlOf(w);
    r.strehl_cost = 1.0 - r.strehl;
    if (sh) {
      if (regrid) {
        if (!offsets[i].actuators_m.empty())
          CheckArgument(Index(offsets[i].actuators_m.size()) == dm->n_active(), fn,
                        "offsets[" + std::to_string(i) + "].actuators_m count", offsets[i].actuators_m.size(),
                        std::to_string(dm->n_active()) + " (the DM's active actuators)");
        r.reference_slopes_rad = sh->ReferenceOffsetForOpd(ExposureOpd(resampled, offsets[i], Image(), dm.get()));
      } else {
        r.reference_slopes_rad = sh->ReferenceOffsetForOpd(w);
      }
    }
    out.push_back(std::move(r));
  }
  return out;
}

nlohmann::json ModalContentJson(const DesignPupil& pupil, const std::vector<Image>& opds) {
  std::vector<DesignFrameReport> fits(opds.size());
  for (std::size_t i = 0; i < opds.size(); ++i) {
    CheckArgument(ShapeOf(opds[i]) == ShapeOf(pupil.amplitude), "ModalContentJson",
                  "opds[" + std::to_string(i) + "] shape", ToString(ShapeOf(opds[i])),
                  "the pupil grid " + ToString(ShapeOf(pupil.amplitude)));
    ModalContent(pupil, opds[i], &fits[i]);
  }
  return ModalContentJson(fits);
}

nlohmann::json ModalContentJson(const std::vector<DesignFrameReport>& frames) {
  nlohmann::json noll = nlohmann::json::array(), per_frame = nlohmann::json::array(), beyond = nlohmann::json::array();
  std::vector<double> sum_abs(kModalContentNoll - 1, 0.0), power(kModalContentNoll - 1, 0.0);
  for (int j = 2; j <= kModalContentNoll; ++j) noll.push_back(j);
  for (const DesignFrameReport& f : frames) {
    CheckArgument(f.zernike_m.size() == kModalContentNoll, "ModalContentJson", "zernike_m size", f.zernike_m.size(),
                  std::to_string(kModalContentNoll) + " (Noll 1.." + std::to_string(kModalContentNoll) + ")");
    nlohmann::json c = nlohmann::json::array();
    for (int j = 2; j <= kModalContentNoll; ++j) {
      const double v = f.zernike_m[j - 1] / kNm;
      c.push_back(v);
      sum_abs[j - 2] += std::abs(v);
      power[j - 2] += v * v;
    }
    per_frame.push_back(c);
    beyond.push_back(f.beyond_m / kNm);
  }
  std::vector<double> rms(power.size());
  for (std::size_t k = 0; k < power.size(); ++k) rms[k] = frames.empty() ? 0.0 : std::sqrt(power[k] / frames.size());
  return {{"basis", "Noll Zernike modes, unit RMS over the unobstructed disc; least squares over the pupil; piston "
                    "dropped"},
          {"units", "nm of wavefront OPD RMS"},
          {"noll", noll},
          {"frames", per_frame},
          {"beyond_nm", beyond},
          {"sum_abs_nm", sum_abs},
          {"power_nm2", power},
          {"rms_over_frames_nm", rms}};
}

nlohmann::json DesignFileJson(const std::string& name, const SceneSpec& scene, const DesignResult& result,
                              const DesignCriterion& objective, const std::vector<DesignFrameReport>& frames) {
  CheckArgument(frames.size() == result.offsets.size(), "DesignFileJson", "frames count", frames.size(),
                std::to_string(result.offsets.size()) + " (one report per offset)");
  nlohmann::json j;
  j["name"] = name;
  nlohmann::json list = nlohmann::json::array();
  for (const DmOffset& o : result.offsets) list.push_back(DmOffsetToJson(o));
  j["frames"] = list;
  const DesignSummary& s = result.summary;
  nlohmann::json d;
  d["method"] = objective.method();
  d["parameterisation"] = s.parameterisation;
  d["scene"] = scene.source;
  d["frames_n"] = scene.frames;
  d["r"] = scene.r;
  if (const auto* a = dynamic_cast<const DesignObjective*>(&objective)) {
    const DesignObjectiveOptions& oo = a->options();
    d["comment"] = "objective A: closed-form expected MSE of the Tikhonov/Wiener reconstructor, averaged over AO PSF "
                   "realisations (design/design_objective.hpp)";
    d["reconstructor"] = {{"prior", ToString(oo.reconstructor.prior)},
                          {"lambda", oo.reconstructor.lambda},
                          {"noise_sigma", oo.noise_sigma},
                          {"object_spectrum", oo.object_power_spectrum.size() ? "given" : "wiener-consistent"}};
    d["screens_per_exposure"] = oo.screens;
  } else if (const auto* b = dynamic_cast<const EmpiricalDesignObjective*>(&objective)) {
    const EmpiricalDesignOptions& ob = b->options();
    d["comment"] = "objective B: mean loss of the MAP reconstructor over training scenes x AO PSF realisations, "
                   "gradient by implicit differentiation (design/design_empirical.hpp)";
    d["reconstructor"] = {{"method", "map"},
                          {"prior", ToString(ob.map.prior)},
                          {"lambda", ob.map.lambda},
                          {"epsilon", ob.map.epsilon},
                          {"noise_sigma", ob.noise_sigma},
                          {"loss", ToString(ob.loss)},
                          {"loss_epsilon", ob.loss_epsilon},
                          {"training_scenes", ob.training_scenes.size()}};
    d["screens_per_exposure"] = ob.screens;
  }
  d["realisations"] = objective.realisations();
  d["grid_hr_px"] = objective.optics().grid;
  d["ao_model"] = objective.optics().ao ? "analytic" : "none";
  d["objective"] = {{"raster", s.raster_objective},
                    {"start", s.initial_objective},
                    {"final", s.final_objective},
                    {"invisible_floor", s.invisible_floor},
                    {"relative_to_raster", s.raster_objective > 0 ? s.final_objective / s.raster_objective : 1.0},
                    {"units", std::string(objective.method()) == "expected-mse"
                                  ? "expected squared error per HR pixel, object units"
                                  : "mean loss per HR pixel over the training scenes, object units"}};
  if (!std::isfinite(s.invisible_floor)) d["objective"]["invisible_floor"] = nullptr;
  d["summary"] = s.FullReport(/*include_time=*/false);  // the file is a product: same inputs, same bytes
  d["iterations"] = s.iterations;
  d["evaluations"] = s.evaluations;
  nlohmann::json fr = nlohmann::json::array();
  bool slopes = false;
  for (const DesignFrameReport& r : frames) {
    nlohmann::json e = {{"rms_nm", r.rms_m / kNm}, {"strehl", r.strehl}, {"strehl_cost", r.strehl_cost}};
    if (r.reference_slopes_rad.size()) {
      slopes = true;
      e["reference_slopes_rad"] = std::vector<double>(r.reference_slopes_rad.data(),
                                                      r.reference_slopes_rad.data() + r.reference_slopes_rad.size());
    }
    fr.push_back(e);
  }
  d["frames"] = fr;
  d["modal_content"] = ModalContentJson(frames);
  if (slopes && scene.telescope.ao)
    d["wfs"] = {{"model", "shack-hartmann-geometric"},
                {"lenslets_across", scene.telescope.ao->wfs.lenslets_across},
                {"valid_subapertures", frames.front().reference_slopes_rad.size() / 2},
                {"pupil_grid_px", SensorPupilGrid(scene)},
                {"slope_order", "the sensor's measurement order: x slopes of the valid lenslets, then y slopes"},
                {"units", "rad of wavefront tilt"}};
  j["design"] = d;
  return j;
}

void WriteDesignFile(const std::string& path, const nlohmann::json& design) {
  AtomicWrite(path, [&](const std::string& tmp) {
    std::ofstream out(tmp);
    if (!out) throw IoError(tmp, "cannot open for writing");
    out << design.dump(2) << "\n";
    if (!out) throw IoError(tmp, "write failed");
  });
}

}  // namespace aosr
