// Model PSFs from the point sources in the frames themselves ("stars" PSFs), for measured data without an
// instrument model. The reference idea is Anderson & King (2000, PASP 112, 1360): an oversampled empirical PSF
// from many stars at different sub-pixel phases, with positions and fluxes fitted iteratively and neighbours
// subtracted. The formulation here is the project's own forward model (core/forward_model.hpp):
//
//     y_i = D_r( h_i ⊛ x ) + b_i + n_i,     x = Σ_j f_j δ(· − p_j),     h_i = shift(h, o_i)
//
//  y_i  frame i in e⁻ (camera pixels), b_i its background (one constant per frame, fitted).
//  x    the stars: HR-frame positions p_j (HR px, image.hpp's pixel-centre convention) and fluxes f_j (e⁻ per
//       frame), shared by all frames (the sky does not move; the pointing does).
//  o_i  frame i's offset (HR px): what the dataset's model PSFs carry (forward_model.hpp: "a sub-pixel pointing
//       offset is part of h_i"), here the commanded DM tip/tilt shifts · r.
//  h    ONE shared PSF at HR sampling, K × K, centred at (K/2, K/2), unit sum. One shared PSF and per-frame
//       shifts because that is how a dataset's frames differ when its DM offsets are tip/tilt shifts (raster
//       designs); frames whose offsets change the PSF's shape (Zernike or actuator offsets) are refused: a
//       shared shape would be wrong for them. The pixel box D_r is applied by the model, not baked into h.
//
// Given the stars, the frames are LINEAR in h: D_r(h ⊛ S_i) with S_i = Σ_j f_j δ(· − p_j − o_i). So h and the
// N backgrounds b_i are the solution of one weighted, lightly ridge-regularised least-squares problem over all
// frames and all stars' pixels at once (preconditioned conjugate gradients on AᵀWA + Λ; the convolution with the
// star field, S_i's spectrum summed from the positions with signed frequencies, runs by FFT on the HR frame
// padded by K so nothing wraps, as the simulator renders). The backgrounds are solved with h because in a
// crowded field the stars' K × K footprints tile the frame: a pedestal in h would otherwise stand in for a
// background error. Λ is a ridge λ(ρ) = regularisation · d · (1 + (ρ / 2r)²), d the centre pixel's diagonal of
// AᵀWA and ρ the HR px from the centre: the core is shrunk by about `regularisation`, the far wings (few
// photons, unmodelled faint stars) more, toward 0. Every star's pixels, neighbours included, enter jointly:
// crowding is modelled, not avoided. With N frames at distinct sub-pixel offsets each star
// samples N of the r² HR phases; the K × K support (K much smaller than the frame) lets many stars at random
// phases fill the rest (Anderson & King's single-image oversampling).
//
// Then, given h, each star's position and flux are refined by Gauss-Newton on its own pixels (a box of
// ±fit_radius_px camera px, all frames jointly) with every other star subtracted (Gauss-Seidel over the stars,
// brightest first), h is solved again, and so on for `rounds` rounds. Stars are found in frame 0: in round 0
// as valid pixels above b + detection_sigma · σ (σ: the robust neighbour-difference estimate of
// EstimateBackgroundSigma, b the median) that are the largest valid pixel within ±fit_radius_px (isolated, so
// that an Airy ring or speckle of a bright star is not taken for a star), in later rounds as 3 × 3 local maxima
// of the residual above both detection_sigma · √(σ² + model) and 10 % of the model there (a faint star next to a
// bright one, not the imperfect subtraction of the bright one), at least 2 camera px from a known star. Without
// given weights σ is re-estimated each round from the residual's pixels where the model is below σ² (neither the
// stars' gradients nor their photon noise inflate it). A detection touching an invalid pixel (saturated or bad) is not fitted: it is
// counted as saturated and the pixels within 2·fit_radius_px + 2 camera px of it get weight 0 in every frame,
// so its unmodelled light cannot enter h. Stars on the frame's outermost pixel ring are not detected. A star
// whose fitted flux falls below 3 σ_flux (e.g. a speckle or Airy-ring maximum of a bright star taken for a
// star in round 0) or that moves off its detection by more than 1.5 camera px is dropped.
//
// Centring (image.hpp): the fitted h is renormalised to unit sum (the fluxes take the inverse factor) and
// shifted (Fourier) so that the FIRST MOMENT OF ITS CORE, the pixels within 3 camera px (3 r HR px) of the
// centre, is at the centre pixel (K/2, K/2); the stars' positions take the opposite shift. The core, not the
// whole window: the wings' noise times their lever arm would move a full-window moment by a tenth of a pixel.
// For a symmetric PSF the two agree (KernelCentroid, DatasetOffsets::kPsfCentroids, reads the full one). Data cannot tell a shift of h from a shift of all the stars, so this is a convention: the offsets
// o_i carry the frames' pointing, h carries none. Any common pointing error (a tip/tilt bias) then appears as
// a shift of the reconstruction (an astrometric offset), not as a PSF error.
//
// Weights: the dataset's inverse variances when it has them (e⁻⁻²; saturated and bad pixels 0), else
// valid / (σ_i² + max(model, 0)): background noise plus the stars' photon noise from the current model.
// Unit sum over the window: light the true PSF has beyond K × K (a seeing halo) is not represented, so h's core
// is high by that fraction; choose K to hold the halo (the default ±16 camera px).
//
// Point sources only (issue 31 item 4; PSFEx and photutils select stars by size, shape and residual), opt-in
// (reject_extended). From round 1 on, each fitted star's χ² per pixel on its own box (every star subtracted) is compared with the stars' median: a
// star above 3x that median (and above 2) whose residual there also holds more than 10 % of its own model's power
// is not a point source (a nebular knot, a galaxy, a blend; a bright star under a slightly wrong PSF has the χ²
// but not the relative residual); it is rejected (counted in `rejected`) and its box masked in every frame. A structured background can be estimated on
// a mesh and removed first (background_mesh_px, opt-in). At the end the fit must be consistent with point
// sources: a χ² per pixel near the stars above max_chi2_near_stars (default 5; a crowded field on a flat sky
// fits at 1.1) is refused with InvalidArgument naming χ², the stars kept and the rejected, never returned as a
// PSF. Measured on crowded-stars with a dead-leaves "nebula" of 400 e- peak: refused at χ² near the stars 39
// (before: χ²/dof 49 accepted, Tikhonov 4.0 dB against the oracle's 44.6); on the flat sky 45.0 dB, unchanged.
// The rejection is opt-in because on real closed-loop star fields it costs photometry: on bench/psf_knowledge.py's
// J-band field it rejected 40 of ~245 stars (halo mismatch, blends) and the linear output's median |flux error| rose
// from 6.1 % to 9.9 % (K: 0.62 % to 0.54 %); it helps where compact knots are taken for stars (the unit test).
//
// A PSF that varies over the field (issue 31 item 4; grid_ny x grid_nx > 1): h is then G = grid_ny · grid_nx
// PSFs h_g at the nodes of a grid over the HR frame (core/psf_field.hpp: nodes on the frame's edges, bilinear
// between them), and star j is seen through Σ_g w_g(p_j) h_g, the PSF interpolated at its own position: the
// frames stay linear in the h_g (S_{i,g} the star field weighted by w_g), so the same joint least-squares solve
// runs on G K² unknowns (a block-diagonal preconditioner, one block per node). The grid starts from the converged
// single PSF: `rounds` rounds with one PSF, then `rounds` more with the grid (solved from early rounds' crude
// stars, the nodes' scales and shifts, nearly degenerate with their stars' fluxes and positions, swing). This is the grid form of PSFEx's
// polynomial in position and of photutils' GriddedPSFModel, in the interpolation the simulator and the
// reconstructors use (solvers/psf_field_model.hpp), so the result is a field model as it stands. Each node is
// normalised and centred on its own (a field-dependent shift is data's astrometry, carried by the stars). A node
// sees only its share of the stars, so its noise is larger than the single PSF's: a Gaussian prior on the nodes,
// with τ = grid_variation · peak / (1 + (ρ/2r)²) in the weights' units. With grid_degree 0 it ties each node to the
// field's mean, Σ_g ||(h_g − h̄)/τ||² (measured on crowded-stars cut to 64², 100 stars, 2 x 2 grid: each node 7-12 %
// RMS of the peak from the truth with independent nodes, 1.5-2.2 % with this prior, the single PSF 1.0 %). With
// grid_degree d (default 2) the nodes follow a polynomial surface of degree d in position, as PSFEx models the
// variation: the surface departs from the mean with τ, each node from the surface with τ · grid_roughness /
// grid_variation. A grid fine enough to follow the field then pools all the stars, as a polynomial does, and
// keeps the grid's interpolation for the reconstructors (measured in bench/results/wide_field.md). Each
// node needs max(min_stars, ⌈r²/N⌉) stars counted by their weights on it (a star on the node counts 1); fewer is
// an InvalidArgument naming the node, its count, the stars found and the need, advising a coarser grid.
//
// Minimum: max(min_stars, ⌈r²/N⌉) usable (unsaturated, fitted) stars. ⌈r²/N⌉ because N frames give each star
// N of the r² sub-pixel phases an HR PSF needs; min_stars (default 4) so that no single star, blend or cosmic
// ray defines the PSF on its own. Fewer: InvalidArgument naming the count, the saturated ones, the threshold.
#pragma once

#include <string>
#include <vector>

#include "aosr/core/forward_model.hpp"
#include "aosr/core/image.hpp"
#include "aosr/core/psf_field.hpp"
#include "aosr/scene/dataset.hpp"

namespace aosr {

struct StarsPsfOptions {
  // K, the side of the estimated PSF in HR px (even, >= 4 r, at most the HR frame). 0: 32 r (±16 camera px,
  // which holds the core, rings and most of an AO halo at K band), limited by the HR frame. The unknowns are
  // K²; a K below the PSF's extent puts the missing light into the core through the unit-sum normalisation.
  int psf_size_hr_px = 0;
  // Detection threshold in units of the background σ on camera pixels (> 0). 5: spurious noise peaks are
  // ~3e-7 per pixel, so a 256² frame has none.
  double detection_sigma = 5.0;
  // The least number of usable stars (>= 1), before the ⌈r²/N⌉ floor (top of the file).
  int min_stars = 4;
  // Alternations of (h solve, star fits): >= 1. Positions start from 3 × 3 centroids (±0.2 camera px); 4
  // rounds bring them to the noise in the tests.
  int rounds = 4;
  // Ridge λ relative to the mean diagonal of AᵀWA (>= 0): shrinks the components the stars do not constrain
  // (far wings of a field of faint stars) toward 0 and biases constrained ones by about this fraction.
  double regularisation = 1e-4;
  // Half side (camera px, >= 1) of the box each star's position and flux are fitted on.
  int fit_radius_px = 3;
  // Conjugate-gradient iterations per h solve (>= 1) and the relative residual that stops it (in (0, 1)).
  int cg_iterations = 300;
  double cg_tolerance = 1e-5;
  // The most stars modelled (>= 1): the brightest are kept.
  int max_stars = 5000;
  // The background's structure (a nebula, a galaxy's disc) estimated on a mesh of boxes this many camera px wide
  // (3σ-clipped medians, bilinear between box centres) and subtracted before anything else; 0 (default): a
  // constant per frame only. [4, 4096] or 0. Opt-in: on the tests' small crowded frames the boxes' medians still
  // carry the stars' wings (a 1 % background bias at 16 px), and residual structure is detected as stars.
  int background_mesh_px = 0;
  // The fit must be consistent with point sources: above this χ² per pixel near the stars (chi2_near_stars) the
  // estimate is refused with InvalidArgument naming χ² and the stars kept. 0: no check. Default 5 (a crowded
  // field on a flat or meshed sky fits at 1.1-1.3).
  double max_chi2_near_stars = 5.0;
  // Reject fitted sources whose residual is not a point source's (top of the file). Default false: it costs
  // photometry on real star fields (measured above).
  bool reject_extended = false;
  // Stars known beforehand (a catalogue: HR-frame px, e⁻ per frame, as Dataset::stars): used instead of the
  // round-0 detection as the starting positions and fluxes (still refined; residual detection still adds).
  std::vector<PointSource> known_stars;
  // The field grid (header): grid_ny x grid_nx nodes over the frame, each in [1, 16]; 1 x 1 (default): one PSF.
  int grid_ny = 1, grid_nx = 1;
  // With a grid: the expected difference of a node's PSF from the field's mean, as a fraction of the PSF's peak at
  // the centre (> 0), falling into the wings as 1/(1 + (ρ/2r)²): a Gaussian prior Σ_g ||(h_g − h̄)/τ||² added to the
  // χ² of the h solve (header). Stars bright enough to measure a node's difference override it; where a node's
  // stars are faint (or its wings, where they give little) the node leans on the mean. 0.3: an AO PSF's peak
  // changes by tens of per cent over a wide field (Strehl 0.6 of on-axis at θ0, issue 31).
  double grid_variation = 0.3;
  // With a grid: the degree of a polynomial surface in position that the nodes follow (PSFEx's model of the
  // variation, as a prior on the grid; monomials u^a v^b, a + b <= d, each power below the grid's nodes on its
  // axis): d in [1, 4] lets the surface depart from the nodes' mean with grid_variation and each node depart from
  // the surface with grid_roughness (a fraction of the peak as grid_variation, > 0); 0 ties every node to the
  // nodes' mean with grid_variation. On a 2 x 2 grid degree >= 1 spans every node, so it is the same as 0.
  int grid_degree = 2;
  double grid_roughness = 0.005;
  bool IsValid(std::string* why) const;
};

struct StarsPsfResult {
  Image psf;                          // h: K × K, unit sum, first moment at (K/2, K/2)
  ImageStack psfs;                    // per frame h shifted by offsets[i] (padded so no shift wraps): the model
  std::vector<FrameOffset> offsets;   // o_i, HR px
  std::vector<PointSource> stars;     // fitted stars (HR-frame px, e⁻ per frame), brightest first
  std::vector<double> background_e;   // b_i, e⁻ per camera pixel
  int detected = 0;                   // detections over all rounds (before dropping)
  int used = 0;                       // stars in the final fit (== stars.size())
  int saturated = 0;                  // detections touching invalid pixels, masked out
  int dropped = 0;                    // detections dropped (flux below 3 σ, or moved > 1.5 camera px)
  int rejected = 0;                   // fitted detections rejected as not point-like (their residual), masked
  int background_mesh_px = 0;         // the mesh used (0: none)
  int min_required = 0;               // max(min_stars, ⌈r²/N⌉) (per node with a field grid)
  // A field grid (grid_ny x grid_nx > 1): the grid, the nodes' PSFs (K x K, unit sum, centred), per node the
  // per-frame PSFs as `psfs` (field_psfs[g][i]: what DatasetProblem's field model takes), and each node's star
  // count (Σ_j w_g(p_j)). psf and psfs are then the PSF interpolated at the frame's centre. Empty without a grid.
  PsfFieldGrid grid;
  ImageStack node_psfs;
  std::vector<ImageStack> field_psfs;
  std::vector<double> node_stars;
  int grid_degree = 0;                // the nodes' prior as fitted (options.grid_degree, roughness); 0 without a grid
  double grid_roughness = 0.0;
  // The fit's quality: Σ w·res² / dof over every pixel of non-zero weight, dof = n − K² − 3·stars − N (0 when
  // dof <= 0), and Σ w·res² / n over the pixels within fit_radius_px of a fitted star (no dof correction): ~1 when
  // the weights are the noise's inverse variances and the model fits; above where the PSF or the stars do not.
  double chi2_per_dof = 0.0;
  double chi2_near_stars = 0.0;
  Index dof = 0;
  int rounds = 0;
  int cg_iterations_last = 0;         // iterations of the final h solve
  bool cg_converged = true;           // the final h solve met cg_tolerance (false: it stopped at cg_iterations)
  int cg_iterations_total = 0;        // over every h solve of every round
  double seconds = 0.0;
  std::string BriefReport() const;    // "stars PSF: 123 stars (2 saturated, 5 dropped), K = 64 HR px, chi2/dof ..."
};

// From frames in e⁻ (N, camera px), their validity masks (1 usable / 0 not; same shapes), optional
// inverse-variance weights (e⁻⁻², empty: from the background and the model, top of the file), the frames'
// offsets (HR px, N of them) and r. Throws InvalidArgument naming the argument (shapes, options) or what the
// frames lack (no detection, too few usable stars, only saturated ones).
StarsPsfResult EstimateStarsPsf(const ImageStack& frames_e, const ImageStack& valid, const ImageStack& weights_e,
                                const std::vector<FrameOffset>& offsets_hr, int r,
                                const StarsPsfOptions& options = {});

// From a dataset: its frames in e⁻, validity masks and inverse variances (when it has them, ADU⁻² → e⁻⁻²),
// offsets from its DM tip/tilt shifts (shift_px · r; zero when it has none). InvalidArgument when a DM offset
// has Zernike or actuator terms (frames whose PSF shapes differ).
StarsPsfResult EstimateStarsPsf(const Dataset& dataset, const StarsPsfOptions& options = {});

// Shifts a centred kernel by (dy, dx) of its pixels with band-limited (Fourier) interpolation, periodic in its
// window: the content moves toward +y, +x. Exposed for the tests and the per-frame PSFs.
Image FourierShiftKernel(const Image& kernel, double dy, double dx);

}  // namespace aosr
