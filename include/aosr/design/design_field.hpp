// Phase design over a wide field (issue 31 item 7): objective A averaged over the field points of a scene's
// psf_field.
//
// The DM is conjugate to the ground (the pupil), so its offsets w_dm,i are common to every direction of the
// field, while the AO residual, and with it the nominal long-exposure factor T(f) and the realised PSFs, change
// with the angle from the guide star (anisoplanatism: analytic_ao.hpp section 2). A design made on axis can
// therefore advise differently from one made for the field a wide camera is used for. With a psf_field the
// design minimises the field mean of objective A (design_objective.hpp):
//     J_field(w) = (1/K) Σ_k J_k(w),   ∂J_field/∂w_i = (1/K) Σ_k ∂J_k/∂w_i,
// where J_k is objective A with the analytic AO model at node k's direction (AnalyticAoAt, scene/preset_psf.hpp)
// and the K nodes are the psf_field grid's (scene_spec.hpp, PsfFieldSpec). Every J_k sees the same DM offsets and
// the same pupil, object prior and noise; node k's AO realisations are drawn with seed + k (a sample-average
// approximation per node, as objective A's own). The mean weights the nodes equally: the grid's nodes sample
// the frame evenly (core/psf_field.hpp), so J_field approximates the MSE averaged over the frame's area.
//
// Cost: K times objective A's (each node its own PSFs and pull-back); the DM offsets' PSFs are the same at
// every node only without AO, which a psf_field excludes.
//
// API rules: the constructor validates (InvalidArgument naming the field); Evaluate is const and thread-safe as
// objective A's is.
#pragma once

#include <memory>
#include <vector>

#include "aosr/ao/atmosphere.hpp"
#include "aosr/design/design_objective.hpp"
#include "aosr/scene/scene_spec.hpp"

namespace aosr {

// The design optics at each node of the scene's psf_field (DesignOpticsFromScene with the analytic AO model at
// the node's direction), with the nodes' directions from the guide star. Empty without a psf_field.
// InvalidArgument (from AnalyticAoAt) for a direction the analytic model cannot reach.
struct FieldDesignOptics {
  std::vector<DesignOptics> optics;
  std::vector<FieldDirection> directions;
  int grid_y = 0, grid_x = 0;
};
FieldDesignOptics DesignOpticsOverField(const SceneSpec& scene);

class FieldDesignObjective : public DesignCriterion {
 public:
  // One objective A per node (options.seed + k for node k's realisations); at least one node, all with the
  // same pupil sampling, wavelength, r and grid.
  FieldDesignObjective(const FieldDesignOptics& field, int frames, const DesignObjectiveOptions& options);

  int nodes() const { return int(nodes_.size()); }
  const DesignObjective& node(int k) const { return *nodes_[std::size_t(k)]; }
  const FieldDirection& direction(int k) const { return directions_[std::size_t(k)]; }
  // J_k of node k alone (no gradient).
  double EvaluateNode(int k, const std::vector<Image>& dm_opds) const { return node(k).Evaluate(dm_opds); }

  int frames() const override { return nodes_.front()->frames(); }
  // The node nearest the guide star (its optics describe the design file's instrument).
  const DesignOptics& optics() const override { return nodes_[std::size_t(nearest_)]->optics(); }
  int realisations() const override { return nodes_.front()->realisations(); }
  double invisible_floor() const override;  // the nodes' mean
  const char* method() const override { return "expected-mse"; }

 private:
  double EvaluateImpl(const std::vector<Image>& dm_opds, std::vector<Image>* grad) const override;

  std::vector<std::unique_ptr<DesignObjective>> nodes_;
  std::vector<FieldDirection> directions_;
  int nearest_ = 0;
};

}  // namespace aosr
