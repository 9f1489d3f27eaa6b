// Bindings of the optics side (through the scene layer's telescope presets): aosr.psf(), the PSF of a
// telescope preset as `aosr psf` computes it (scene/preset_psf.hpp: the same library call).
#include <cmath>

#include "aosr/core/error.hpp"
#include "aosr/scene/preset_psf.hpp"
#include "aosr/scene/telescope.hpp"
#include "bindings.hpp"
#include "common.hpp"

namespace aosr::python {

void BindOptics(py::module_& m) {
  m.def(
      "psf",
      [](py::object preset_object, std::optional<std::string> mode, py::object offsets, int r, double pixel_lod,
         int size, const std::string& sensor, double exposure, double settling, std::uint64_t seed, bool antithetic,
         double field_angle, py::object field_direction) {
        constexpr double kArcsecPerRad = 180.0 * 3600.0 / M_PI;
        const std::string preset = PathString(preset_object);
        PresetPsfOptions o;
        o.mode = mode.value_or("");
        if (!offsets.is_none()) {
          // {noll: nm} or [(noll, nm), ...]
          py::object items = py::isinstance<py::dict>(offsets) ? offsets.attr("items")() : offsets;
          for (py::handle item : items) {
            const py::sequence pair = py::reinterpret_borrow<py::sequence>(item);
            if (pair.size() != 2) OptionError("offsets", py::repr(item), "{noll: nm} or [(noll, nm), ...]");
            o.offsets.push_back({pair[0].cast<int>(), pair[1].cast<double>()});
          }
        }
        o.r = r;
        o.pixel_lod = pixel_lod;
        o.size = size;
        o.sensor = ParseSensorKind(sensor);
        o.exposure_s = exposure;
        o.settling_s = settling;
        o.seed = seed;
        o.antithetic = antithetic;
        if (!field_direction.is_none()) {
          if (field_angle != 0.0)
            OptionError("field_direction", py::repr(field_direction),
                        "not together with field_angle (field_angle=A is field_direction=(A, 0))");
          if (!py::isinstance<py::sequence>(field_direction) || py::isinstance<py::str>(field_direction) ||
              py::len(field_direction) != 2)
            OptionError("field_direction", py::repr(field_direction), "(x, y) in arcsec from the guide star");
          const py::sequence xy = py::reinterpret_borrow<py::sequence>(field_direction);
          o.field_direction = {xy[0].cast<double>() / kArcsecPerRad, xy[1].cast<double>() / kArcsecPerRad};
        } else {
          o.field_direction = {field_angle / kArcsecPerRad, 0.0};
        }
        std::string why;
        if (!o.IsValid(&why)) throw InvalidArgument("aosr.psf: invalid " + why);
        PythonProgress poll;
        PresetPsf p = WithoutGil([&] {
          const TelescopePreset t = LoadTelescopePreset(preset);
          return ComputePresetPsf(t, o);
        });
        poll.RaiseIfPending();
        py::dict d;
        d["preset"] = preset;
        d["mode"] = p.mode;
        d["wavelength_m"] = p.sampling.wavelength_m;
        d["pixel_scale_rad"] = p.sampling.pixel_scale_rad;
        d["pixel_scale_lambda_over_d"] = 1.0 / p.lambda_over_d_px;
        d["strehl"] = p.strehl;
        d["fwhm_px"] = p.fwhm_px;
        d["fwhm_lambda_over_d"] = p.fwhm_px / p.lambda_over_d_px;
        d["fwhm_major_lambda_over_d"] = p.fwhm_major_px / p.lambda_over_d_px;
        d["fwhm_minor_lambda_over_d"] = p.fwhm_minor_px / p.lambda_over_d_px;
        d["elongation"] = p.elongation;
        d["major_axis_angle_deg"] = p.major_axis_angle_deg;
        d["field_direction_arcsec"] = py::dict(py::arg("x") = p.field_direction.x_rad * kArcsecPerRad,
                                               py::arg("y") = p.field_direction.y_rad * kArcsecPerRad);
        d["field_angle_arcsec"] = p.field_direction.Norm() * kArcsecPerRad;
        d["isoplanatic_angle_arcsec"] =
            p.isoplanatic_angle_rad > 0 && std::isfinite(p.isoplanatic_angle_rad)
                ? py::object(py::float_(p.isoplanatic_angle_rad * kArcsecPerRad))
                : py::object(py::none());
        py::dict ee;
        ee["radius_lambda_over_d"] = std::vector<int>{1, 2, 5};
        ee["fraction_of_window"] = p.encircled_energy;
        d["encircled_energy"] = ee;
        d["window_sum"] = p.window_sum;
        d["core_centroid_lambda_over_d"] = py::dict(py::arg("y") = p.core_centroid_lod[0], py::arg("x") = p.core_centroid_lod[1]);
        d["residual_rms_nm"] = p.residual_rms_nm;
        if (!p.loop_report.empty())
          d["closed_loop"] = py::dict(py::arg("sensor") = sensor, py::arg("antithetic") = antithetic,
                                      py::arg("report") = p.loop_report);
        d["psf"] = MoveImage(std::move(p.psf));
        return d;
      },
      py::arg("preset"), py::kw_only(), py::arg("mode") = py::none(), py::arg("offsets") = py::none(), py::arg("r") = 2,
      py::arg("pixel_lod") = 0.0, py::arg("size") = 128, py::arg("sensor") = "diffractive", py::arg("exposure") = 0.5,
      py::arg("settling") = 0.1, py::arg("seed") = 1, py::arg("antithetic") = true, py::arg("field_angle") = 0.0,
      py::arg("field_direction") = py::none(),
      R"doc(The science PSF of a telescope preset (a name of data/telescopes/ or a .json path), as `aosr psf`.

mode       'analytic' (long-exposure AO residual) | 'diffraction' | 'closed-loop' (Monte-Carlo); None: analytic
           when the preset has atmosphere and AO, else diffraction
offsets    DM offsets as {noll: nm RMS} or [(noll, nm), ...] (the CLI's --offset J=NM)
r          pixel = camera pixel / r, unless pixel_lod > 0 gives it in lambda/D
size       PSF side in pixels
sensor, exposure, settling, seed   closed loop only: WFS model, recorded and settling time [s], seed
antithetic closed loop only: average the atmosphere's PSF and its negation's (default True; the stretch's
           random tip/tilt cancels, as in a scene); False: one realisation
field_angle      science direction: arcsec from the guide star along +x (anisoplanatism; default 0, on axis)
field_direction  (x, y) arcsec from the guide star instead (x along columns, y along rows)
Returns the dict `aosr psf --json` prints (without 'seconds') plus 'psf': the (size, size) PSF, centred,
normalised so that the whole focal plane sums to 1 (no copy).)doc");
}

}  // namespace aosr::python
