#!/usr/bin/python3
"""Accuracy in time of super-resolved video (issue 34 item 4): on a sky that moves and varies, each output against
the truth at its time, for the streaming outputs and the baselines, and how that depends on the speed.

Data: the simulator's own sequences (issue 34 item 1; nothing is committed but the results) of
data/scenes/video-planet.json: the paper's 8 m telescope in K behind the analytic AO PSF, r = 4, 64² frames (a 256²
HR grid), the 2 × 2 raster of half-pixel shifts (N = 4 phases) cycled at 50 frames/s, 1 % peak Gaussian noise. The
sky: a limb-darkened planet with bright spots turning once in 1.6 s, a companion star (3e4 e⁻) crossing the dark
sky along +x at SPEED HR px per frame (the scene's velocity set per run), a star varying as 1 + 0.8 sin(2π t / 0.4 s).
The frames come from the simulator (the PSF's window, linear convolution, pixel integration, detector), not from the
reconstructors' model, and the truth at each exposure's mid-time from the same run (Dataset.truth_frames).

Methods, each scored against the truth at the time of its output (its newest frame: what a viewer sees then), after
the best global sub-pixel alignment (aosr.compare_images_aligned; the frames' own DM shifts make bicubic's grid
differ): PSNR over the field within the trustworthy border, the companion's flux in an aperture at its true
position (a fraction of the truth's: smear moves light out), and the variable star's light curve (aperture flux
against time; RMS error over the mean flux):
  * sliding: aosr.video, Tikhonov (λ chosen once by GCV on the first window), an output per frame;
  * cycle:   the same, one output per cycle of the 4 phases;
  * tv:      aosr.video "tv", warm-started (10 ADMM iterations per output);
  * batch:   aosr.reconstruct (Tikhonov, GCV) of the whole sequence as one static scene, against every time;
  * bicubic: each frame alone, bicubic ×4 (aosr.bicubic).

Outputs: a markdown table (per method and speed), a plot (at one speed the light curve and the field's PSNR against
time; the companion's flux and the field's PSNR against speed), and a picture of the sequence (truth, sliding
Tikhonov and bicubic at four times).

Usage: /usr/bin/python3 bench/video_accuracy.py [--build build] [--out bench/results/video_accuracy.md]
       [--plot bench/results/video_accuracy.png] [--picture bench/results/video_frames.png] [--frames 48]
       [--speeds 0,0.25,0.5,1,2] [--plot-speed 1]
"""
import argparse
import os
import sys

import numpy as np

R = 4
RATE = 50.0        # frames per second (the scene's frame_interval_s = 0.02)
APERTURE = 3.0     # HR px (0.75 λ/D): the photometric aperture's radius, small enough to see the smear
COMPANION, VARIABLE = 1, 2  # the scene's objects


def hr_position(y_px, x_px):
    """Camera pixel coordinates to HR ones (camera pixel c spans HR pixels c·r .. c·r + r − 1)."""
    return ((y_px + 0.5) * R - 0.5, (x_px + 0.5) * R - 0.5)


def aperture(image, centre, radius=APERTURE):
    """The sum within `radius` HR px of centre (periodic), the photometry of a point source."""
    yy, xx = np.mgrid[0:image.shape[0], 0:image.shape[1]]
    dy = (yy - centre[0] + image.shape[0] / 2) % image.shape[0] - image.shape[0] / 2
    dx = (xx - centre[1] + image.shape[1] / 2) % image.shape[1] - image.shape[1] / 2
    return float(image[dy * dy + dx * dx <= radius * radius].sum())


def score(aosr, truth, estimate, companion, variable, crop, peak):
    """Field PSNR after the best global alignment, and the aperture fluxes of the companion (as a fraction of the
    truth's) and of the variable star, in the aligned estimate and in the truth (the sky there is dark)."""
    a = aosr.compare_images_aligned(truth, estimate, crop=crop, peak=peak)
    # The estimate is the truth moved by offset_px: moved back for the photometry too (0 when not applied).
    dy, dx = a["offset_px"]["dy"], a["offset_px"]["dx"]
    e = aosr.fourier_shift(estimate, -dy, -dx) if (dy or dx) else estimate
    comp = aperture(e, companion) / aperture(truth, companion)
    return a["aligned"]["psnr_db"], comp, aperture(e, variable), aperture(truth, variable)


def summarise(v):
    """Mean PSNR, mean companion fraction, the light curve's RMS error over its mean, the count."""
    return (float(np.mean(v[:, 1])), float(np.mean(v[:, 2])),
            float(np.sqrt(np.mean((v[:, 3] - v[:, 4]) ** 2)) / float(np.mean(v[:, 4]))), len(v))


def run(aosr, base, speed, methods, comp_yx, variable, frames, ao=None):
    """Simulates the scene with the companion at `speed` HR px per frame (and the `ao` section when given),
    reconstructs it with `methods` and scores every output: per method rows (frame, psnr, companion fraction,
    variable's flux, its truth, time); the truths; the sliding outputs and bicubic images by frame."""
    scene = dict(base)
    # SPEED HR px per frame: speed · RATE / R camera px per second along +x.
    scene["objects"] = [dict(o) for o in base["objects"]]
    scene["objects"][COMPANION]["variation"] = {"velocity_px_per_s": [0.0, speed * RATE / R]}
    if ao:
        scene["ao"] = ao
    ds = aosr.simulate(aosr.Scene(scene, "video-planet.json"))
    truths = np.asarray(ds.truth_frames)
    times = np.asarray(ds.times_s)
    frames_e = np.asarray(ds.frames_electrons())
    crop = ds.trustworthy_border_px * R
    inner = truths[:, crop:-crop, crop:-crop]
    peak = float((inner.max(axis=(1, 2)) - inner.min(axis=(1, 2))).max())
    companions = [hr_position(comp_yx["y_px"], comp_yx["x_px"] + speed * RATE / R * t) for t in times]
    scores = {m: [] for m in methods}

    def add(method, j, estimate):
        scores[method].append((j,) + score(aosr, truths[j], estimate, companions[j], variable, crop, peak) + (times[j],))

    shown = {}
    for method, window, kind in [("sliding", "sliding", "tikhonov"), ("cycle", "cycle", "tikhonov"),
                                 ("tv", "sliding", "tv")]:
        if method not in methods:
            continue
        for _, image, info in aosr.video(ds, kind, window, info=True):
            j = max(info["frames"])
            add(method, j, image)
            if method == "sliding":
                shown[j] = image
    batch = aosr.reconstruct(ds, "tikhonov").image if "batch" in methods else None
    bicubic_shown = {}
    for j in range(frames):
        if batch is not None:
            add("batch", j, batch)
        if "bicubic" in methods:
            b = aosr.bicubic(frames_e[j], R)
            add("bicubic", j, b)
            bicubic_shown[j] = b
    return scores, truths, shown, bicubic_shown


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--build", default="build")
    ap.add_argument("--out", default="")
    ap.add_argument("--plot", default="")
    ap.add_argument("--picture", default="")
    ap.add_argument("--frames", type=int, default=48)
    ap.add_argument("--speeds", default="0,0.25,0.5,1,2")
    ap.add_argument("--plot-speed", type=float, default=1.0)
    ap.add_argument("--closed-loop", action="store_true",
                    help="also run the plot speed with the closed loop (one continuous loop through the sequence)")
    args = ap.parse_args()
    sys.path.insert(0, os.path.join(args.build, "python"))
    import aosr  # noqa: E402  (the build's module)

    base = aosr.read_json(aosr.data_path("scenes", "video-planet.json"))
    base["sequence"]["frames"] = args.frames
    comp_yx = base["objects"][COMPANION]["catalogue"][0]
    var_yx = base["objects"][VARIABLE]["catalogue"][0]
    variable = hr_position(var_yx["y_px"], var_yx["x_px"])
    methods = ["sliding", "cycle", "tv", "batch", "bicubic"]
    table = {}
    light_curves = {}
    pictures = None
    speeds = [float(v) for v in args.speeds.split(",")]
    for speed in speeds:
        scores, truths, shown, bicubic_shown = run(aosr, base, speed, methods, comp_yx, variable, args.frames)
        for m in methods:
            v = np.array(scores[m])
            table[(m, speed)] = summarise(v)
            if speed == args.plot_speed:
                light_curves[m] = v
        if speed == args.plot_speed:
            picks = [j for j in (7, 19, 31, 43) if j in shown]
            pictures = [(truths[j], shown[j], bicubic_shown[j], j) for j in picks]
        print(f"speed {speed:g}: " + ", ".join(
            f"{m} {table[(m, speed)][0]:.2f} dB, companion {table[(m, speed)][1]:.3f}, variable {table[(m, speed)][2]:.3f}"
            for m in methods), flush=True)

    closed = {}
    if args.closed_loop:
        # One continuous loop through the 48 exposures: the geometric Shack-Hartmann at 800 Hz, each exposure's
        # 20 ms (the frame interval) simulated after 5 ms of settling to its new offset; the model of each phase is
        # the dataset's PSF, the mean of the phase's exposures (what a star in the data would show).
        ao = {"mode": "closed-loop", "sensor": "geometric", "time_per_frame_s": 0.02, "settling_s": 0.005}
        cl_methods = ["sliding", "cycle", "batch"]
        scores, _, _, _ = run(aosr, base, args.plot_speed, cl_methods, comp_yx, variable, args.frames, ao)
        for m in cl_methods:
            closed[m] = summarise(np.array(scores[m]))
        print("closed loop: " + ", ".join(f"{m} {closed[m][0]:.2f} dB" for m in cl_methods), flush=True)

    lines = [
        f"Accuracy in time (bench/video_accuracy.py): the simulator's sequences of data/scenes/video-planet.json "
        f"(paper-8m, analytic AO in K, r = {R}, 64² frames, 256² HR, the half-pixel raster: N = 4 phases at "
        f"{RATE:g} frames/s, {args.frames} frames, 1 % peak noise): a limb-darkened planet with spots turning once "
        "in 1.6 s, a companion star moving along x at SPEED HR px per frame and a star whose flux varies by ±80 % "
        "with a 0.4 s period (20 frames), both on dark sky. Each output is scored against the truth at the time "
        "of its newest frame (what a viewer sees then), after the best global alignment. Cells: field PSNR (dB, "
        "within the trustworthy border) / the companion's flux in a 3 HR px (0.75 λ/D) aperture at its true "
        "position, as a fraction of the truth's (the window's smear moves light out; above 1 at rest for the "
        "deconvolving methods, whose sharpened core has a negative ring outside the aperture, below 1 for "
        "bicubic, whose PSF spreads light beyond it) / the variable star's light curve in the same aperture, RMS "
        "error over its mean flux; means over the outputs (count in brackets).",
        "",
        "| method | " + " | ".join(f"speed {v:g} HR px/frame" for v in speeds) + " |",
        "|---|" + "---|" * len(speeds),
    ]
    for m in methods:
        lines.append(f"| {m} | " + " | ".join(
            f"{table[(m, v)][0]:.2f} / {table[(m, v)][1]:.3f} / {table[(m, v)][2]:.3f} ({table[(m, v)][3]})"
            for v in speeds) + " |")
    if closed:
        lines += ["", f"The closed loop instead of the analytic AO PSF, at speed {args.plot_speed:g} (`--closed-loop`): one "
                  "continuous loop through the exposures (geometric Shack-Hartmann, 800 Hz, 20 ms per exposure after "
                  "5 ms of settling), so the residual changes from frame to frame while each phase's model is the mean "
                  "of its exposures' PSFs.", "",
                  "| method | field PSNR (dB) | companion | variable's light curve |", "|---|---|---|---|"]
        for m, v in closed.items():
            a = table[(m, args.plot_speed)]
            lines.append(f"| {m} | {v[0]:.2f} (analytic {a[0]:.2f}) | {v[1]:.3f} ({a[1]:.3f}) | {v[2]:.3f} ({a[2]:.3f}) |")
    text = "\n".join(lines) + "\n"
    print()
    print(text)
    if args.out:
        with open(args.out, "w") as f:
            f.write(f"<!-- /usr/bin/python3 bench/video_accuracy.py --build {args.build} --frames {args.frames} "
                    f"--speeds {args.speeds} --plot-speed {args.plot_speed:g}{' --closed-loop' if closed else ''} -->\n"
                    + text)
    if args.plot:
        truth_curve = light_curves["sliding"]
        panels = [
            {"title": f"Variable star: aperture flux against time (speed {args.plot_speed:g})",
             "x": {"label": "time of the output (s)"}, "y": {"label": "flux in the aperture (e-)"},
             # The methods first, so that each keeps its colour in every panel; the truth last.
             "series": [{"label": m, "x": list(light_curves[m][:, 5]), "y": list(light_curves[m][:, 3])}
                        for m in methods] +
                       [{"label": "truth", "x": list(truth_curve[:, 5]), "y": list(truth_curve[:, 4])}]},
            {"title": f"Whole field against time (speed {args.plot_speed:g})",
             "x": {"label": "time of the output (s)"}, "y": {"label": "PSNR (dB)"},
             "series": [{"label": m, "x": list(light_curves[m][:, 5]), "y": list(light_curves[m][:, 1])}
                        for m in methods]},
            {"title": "Moving companion: flux in the aperture at its true position",
             "x": {"label": "speed (HR px per frame)"}, "y": {"label": "fraction of the truth's", "min": 0},
             "series": [{"label": m, "x": speeds, "y": [table[(m, v)][1] for v in speeds]} for m in methods]},
            {"title": "Whole field", "x": {"label": "speed (HR px per frame)"}, "y": {"label": "PSNR (dB)"},
             "series": [{"label": m, "x": speeds, "y": [table[(m, v)][0] for v in speeds]} for m in methods]},
        ]
        aosr.write_figure(args.plot, panels, columns=2, panel_width=640)
    if args.picture and pictures:
        # Rows: truth, sliding Tikhonov, bicubic; columns: four times. One asinh stretch for all panels.
        lo, hi = np.percentile(np.concatenate([p[0].ravel() for p in pictures]), [0.5, 99.8])
        gap = 4
        hr = pictures[0][0].shape
        canvas = np.full((3 * hr[0] + 2 * gap, len(pictures) * hr[1] + (len(pictures) - 1) * gap), np.nan)
        for c, (truth, slid, bic, _) in enumerate(pictures):
            for r_, img in enumerate((truth, slid, bic)):
                t = np.flipud(np.clip((img - lo) / (hi - lo), 0, 1))  # FITS rows: row 0 at the bottom
                canvas[r_ * (hr[0] + gap):r_ * (hr[0] + gap) + hr[0], c * (hr[1] + gap):c * (hr[1] + gap) + hr[1]] = \
                    np.arcsinh(t / 0.05) / np.arcsinh(1 / 0.05)
        canvas = np.where(np.isnan(canvas), 1.0, canvas)  # white gaps
        aosr.write_image(args.picture, canvas, stretch="linear", low=0, high=100)
        print("picture: rows truth / sliding Tikhonov / bicubic at frames",
              ", ".join(str(p[3]) for p in pictures))


if __name__ == "__main__":
    main()
