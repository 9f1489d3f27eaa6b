#include "aosr/design/design_field.hpp"

#include <cmath>
#include <string>

#include "aosr/core/error.hpp"
#include "aosr/design/design_psf.hpp"
#include "aosr/scene/preset_psf.hpp"

namespace aosr {

FieldDesignOptics DesignOpticsOverField(const SceneSpec& scene) {
  FieldDesignOptics f;
  if (!scene.psf_field.enabled) return f;
  f.grid_y = scene.psf_field.grid_y;
  f.grid_x = scene.psf_field.grid_x;
  const DesignOptics on_axis = DesignOpticsFromScene(scene);
  const int nodes = scene.FieldGrid().nodes();
  for (int k = 0; k < nodes; ++k) {
    const FieldDirection d = scene.FieldNodeDirection(k);
    DesignOptics o = on_axis;
    // A psf_field needs AO (scene_spec.cpp), but a preset without an atmosphere has no residual to move.
    if (o.ao) o.ao = AnalyticAoAt(scene.telescope, d, "DesignOpticsOverField", "psf_field node " + std::to_string(k));
    f.optics.push_back(std::move(o));
    f.directions.push_back(d);
  }
  return f;
}

FieldDesignObjective::FieldDesignObjective(const FieldDesignOptics& field, int frames,
                                           const DesignObjectiveOptions& options) {
  const char* fn = "FieldDesignObjective";
  CheckArgument(!field.optics.empty(), fn, "field", "no field points", "at least one (a scene with a psf_field)");
  CheckArgument(field.directions.size() == field.optics.size(), fn, "field.directions",
                std::to_string(field.directions.size()) + " directions",
                "one per optics (" + std::to_string(field.optics.size()) + ")");
  const DesignOptics& first = field.optics.front();
  for (std::size_t k = 0; k < field.optics.size(); ++k) {
    const DesignOptics& o = field.optics[k];
    // The DM offsets are shared: every node must see them on the same pupil grid and HR design grid.
    CheckArgument(ShapeOf(o.amplitude) == ShapeOf(first.amplitude) && o.grid == first.grid && o.r == first.r &&
                      o.wavelength_m == first.wavelength_m && o.hr_pixel_rad == first.hr_pixel_rad,
                  fn, "field.optics[" + std::to_string(k) + "]", ToString(ShapeOf(o.amplitude)) + " pupil, grid " +
                  std::to_string(o.grid), "the first node's pupil, grid, r, wavelength and pixel");
    DesignObjectiveOptions node = options;
    node.seed = options.seed + k;
    nodes_.push_back(std::make_unique<DesignObjective>(o, frames, node));
    directions_.push_back(field.directions[k]);
    if (field.directions[k].Norm() < field.directions[std::size_t(nearest_)].Norm()) nearest_ = int(k);
  }
}

double FieldDesignObjective::invisible_floor() const {
  double sum = 0;
  for (const auto& n : nodes_) sum += n->invisible_floor();
  return sum / double(nodes_.size());
}

double FieldDesignObjective::EvaluateImpl(const std::vector<Image>& dm_opds, std::vector<Image>* grad) const {
  const double w = 1.0 / double(nodes_.size());
  double j = 0;
  std::vector<Image> g;
  for (std::size_t k = 0; k < nodes_.size(); ++k) {
    j += w * nodes_[k]->Evaluate(dm_opds, grad ? &g : nullptr);
    if (!grad) continue;
    if (k == 0) {
      grad->assign(g.size(), Image());
      for (std::size_t i = 0; i < g.size(); ++i) (*grad)[i] = w * g[i];
    } else {
      for (std::size_t i = 0; i < g.size(); ++i) (*grad)[i] += w * g[i];
    }
  }
  if (!std::isfinite(j)) throw NumericalError("FieldDesignObjective: the field mean of objective A is not finite");
  return j;
}

}  // namespace aosr
