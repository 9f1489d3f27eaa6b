#!/usr/bin/python3
"""Accuracy in time of super-resolved video (issue 34 item 4): on an object that moves and varies, each output
against the truth at its time, for the streaming outputs and the baselines, and how that depends on the speed.

Data (made here; nothing is committed but the results): the demo scene at r = 4 (`data/scenes/demo.json` with
r = 4 and 64² frames: a 256² HR grid, diffraction-limited PSFs of the paper's 8 m telescope in K, the 2 × 2 raster of
half-pixel shifts, N = 4 phases), simulated once for its PSFs. The object at time t is the demo's truth (a USAF
target with point sources, static) plus
  * a companion (a Gaussian of FWHM 3 HR px, 2000 e⁻ peak) moving along +x at SPEED HR px per frame,
  * a variable star (FWHM 3 HR px) whose peak goes as 1500 (1 + 0.8 sin(2π t / 0.4 s)) e⁻,
both on the darkest sky of the target (its background, less its minimum, is dark between the bars).
Frames: frame j (time j / 50 s) is phase j mod 4 of the object at t_j (periodic convolution with the phase's PSF,
r × r pixel sums, the reconstructors' own model), plus Gaussian noise of 1 % of the brightest noiseless pixel.

Methods, each scored against the truth at the time of its output (the newest frame it uses: what a viewer sees
then), after the best global sub-pixel alignment (aosr.compare_images_aligned): PSNR over the whole field, the
companion's flux in a 3 HR px aperture at its true position (a fraction of the truth's: smear moves light out),
and the variable star's light curve (aperture flux against time; RMS error over the mean flux):
  * sliding: aosr.video, Tikhonov (λ chosen once by GCV on the first window), an output per frame;
  * cycle:   the same, one output per cycle of the 4 phases;
  * tv:      aosr.video "tv", warm-started (10 ADMM iterations per output);
  * batch:   aosr.reconstruct (Tikhonov, GCV) of the whole sequence as one static scene, against every time;
  * bicubic: each frame alone, bicubic ×4 (aosr.bicubic).

Outputs: a markdown table (per method and speed), a plot (the light curve at one speed; the companion's flux and the
field's PSNR against speed), and a picture of the sequence (truth, sliding Tikhonov and bicubic at four times).

Usage: /usr/bin/python3 bench/video_accuracy.py [--build build] [--out bench/results/video_accuracy.md]
       [--plot bench/results/video_accuracy.png] [--picture bench/results/video_frames.png] [--frames 48]
       [--speeds 0,0.25,0.5,1,2] [--plot-speed 1]
"""
import argparse
import json
import os
import shutil
import sys
import tempfile

import numpy as np

R = 4
LR = 64
RATE = 50.0
APERTURE = 3.0  # HR px: the photometric aperture's radius (94 % of a FWHM 3 source's light)


def gaussian(shape, y0, x0, fwhm, peak):
    yy, xx = np.mgrid[0:shape[0], 0:shape[1]]
    s = fwhm / 2.3548
    return peak * np.exp(-((yy - y0) ** 2 + (xx - x0) ** 2) / (2 * s * s))


def dark_places(background):
    """The darkest 13-px-wide row band (the companion's track) and the darkest 13 × 13 spot off it (the variable
    star): apertures there hold the moving sources' light and almost no background."""
    hr = background.shape
    rows = np.array([background[max(0, y - 6):y + 7].mean() for y in range(hr[0])])
    margin = 12
    track = margin + int(np.argmin(rows[margin:hr[0] - margin]))
    best, spot = np.inf, (margin, margin)
    for y in range(margin, hr[0] - margin, 4):
        if abs(y - track) < 24:
            continue
        for x in range(margin, hr[1] - margin, 4):
            v = background[y - 6:y + 7, x - 6:x + 7].mean()
            if v < best:
                best, spot = v, (y, x)
    return track, spot


def truth_at(background, places, j, speed):
    """The object at frame j: the static background, the companion (FWHM 3 HR px, 2000 e- peak) at
    x = 40 + speed * j on the track row, the variable star (FWHM 3, 1500 (1 + 0.8 sin(2 pi t / 0.4 s)) e- peak);
    returns it and the companion's centre."""
    hr = background.shape
    track, spot = places
    t = j / RATE
    companion = (float(track), (40.0 + speed * j) % hr[1])
    x = background.copy()
    x += gaussian(hr, companion[0], companion[1], 3.0, 2000.0)
    x += gaussian(hr, spot[0], spot[1], 3.0, 1500.0 * (1 + 0.8 * np.sin(2 * np.pi * t / 0.4)))
    return x, companion


def aperture(image, centre, radius=APERTURE):
    """The sum within `radius` HR px of centre (periodic), the photometry of a point source."""
    yy, xx = np.mgrid[0:image.shape[0], 0:image.shape[1]]
    dy = (yy - centre[0] + image.shape[0] / 2) % image.shape[0] - image.shape[0] / 2
    dx = (xx - centre[1] + image.shape[1] / 2) % image.shape[1] - image.shape[1] / 2
    return float(image[dy * dy + dx * dx <= radius * radius].sum())


def render(x, psf):
    """D_r(h ⊛ x), periodic: the reconstructors' model."""
    hr = x.shape
    k = np.zeros(hr)
    n = psf.shape[0]
    k[:n, :n] = psf
    k = np.roll(k, (-(n // 2), -(n // 2)), axis=(0, 1))
    blurred = np.fft.irfft2(np.fft.rfft2(x) * np.fft.rfft2(k), s=hr)
    return blurred.reshape(hr[0] // R, R, hr[1] // R, R).sum(axis=(1, 3))


def write_sequence(aosr, folder, frames_e, psfs, sigma):
    folder.mkdir(parents=True)
    aosr.write_fits(folder / "frames.fits", frames_e, dtype="float64")
    aosr.write_fits(folder / "psfs.fits", psfs, dtype="float64")
    # Frames in e⁻ (gain 1, bias 0); the noise level known, so the weights are the same for every window.
    m = {"format": "aosr-manifest", "version": 1, "frames": "frames.fits", "psfs": "psfs.fits", "r": R,
         "gain_e_per_adu": 1.0, "bias_adu": 0.0, "noise": {"model": "peak-fraction", "sigma_e": sigma},
         "sequence": {"slots": [j % len(psfs) for j in range(len(frames_e))],
                      "times_s": [j / RATE for j in range(len(frames_e))]}}
    (folder / "manifest.json").write_text(json.dumps(m))
    return folder


def score(aosr, truth, estimate, background, places, companion, peak):
    """Field PSNR after the best global alignment, and the aperture fluxes of the companion and the variable star
    in the (aligned) estimate less the background's, against the truth's."""
    a = aosr.compare_images_aligned(truth, estimate, peak=peak)
    # The estimate is the truth moved by offset_px: moved back for the photometry too (0 when not applied).
    dy, dx = a["offset_px"]["dy"], a["offset_px"]["dx"]
    e = aosr.fourier_shift(estimate, -dy, -dx) if (dy or dx) else estimate
    spot = places[1]
    comp = (aperture(e, companion) - aperture(background, companion)) / (aperture(truth, companion) -
                                                                          aperture(background, companion))
    var_e = aperture(e, spot) - aperture(background, spot)
    var_t = aperture(truth, spot) - aperture(background, spot)
    return a["aligned"]["psnr_db"], comp, var_e, var_t


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--build", default="build")
    ap.add_argument("--out", default="")
    ap.add_argument("--plot", default="")
    ap.add_argument("--picture", default="")
    ap.add_argument("--frames", type=int, default=48)
    ap.add_argument("--speeds", default="0,0.25,0.5,1,2")
    ap.add_argument("--plot-speed", type=float, default=1.0)
    args = ap.parse_args()
    sys.path.insert(0, os.path.join(args.build, "python"))
    import aosr  # noqa: E402  (the build's module)
    import pathlib

    scene = aosr.load_scene(aosr.data_path("scenes", "demo.json"), {"r": R, "detector.frame_px": LR})
    ds = aosr.simulate(scene, seed=1)
    psfs = np.asarray(ds.psfs)
    background = np.asarray(ds.truth)
    background = background - background.min()  # dark sky between the target's bars
    places = dark_places(background)
    work = pathlib.Path(tempfile.mkdtemp(prefix="aosr_video_accuracy_"))
    rng = np.random.default_rng(34)
    methods = ["sliding", "cycle", "tv", "batch", "bicubic"]
    table = {}
    light_curves = {}
    pictures = None
    speeds = [float(v) for v in args.speeds.split(",")]
    for speed in speeds:
        truths, companions, frames = [], [], []
        for j in range(args.frames):
            x, c = truth_at(background, places, j, speed)
            truths.append(x)
            companions.append(c)
            frames.append(render(x, psfs[j % len(psfs)]))
        sigma = 0.01 * max(float(f.max()) for f in frames)
        frames = np.array([f + sigma * rng.standard_normal(f.shape) for f in frames])
        peak = max(float(x.max()) for x in truths)
        seq = write_sequence(aosr, work / f"speed_{speed:g}", frames, psfs, sigma)
        scores = {m: [] for m in methods}  # (frame, field psnr, companion flux ratio, variable's flux, its truth)

        def add(method, j, estimate):
            scores[method].append((j,) + score(aosr, truths[j], estimate, background, places, companions[j], peak))

        shown = {}
        for method, window, kind in [("sliding", "sliding", "tikhonov"), ("cycle", "cycle", "tikhonov"),
                                     ("tv", "sliding", "tv")]:
            for t, image, info in aosr.video(seq, kind, window, info=True):
                j = int(round(t * RATE))
                add(method, j, image)
                if method == "sliding":
                    shown[j] = image
        batch = aosr.reconstruct(seq, "tikhonov").image
        bicubic_shown = {}
        for j in range(args.frames):
            add("batch", j, batch)
            b = aosr.bicubic(frames[j], R)
            add("bicubic", j, b)
            bicubic_shown[j] = b
        for m in methods:
            v = np.array(scores[m])
            mean_var = float(np.mean(v[:, 4]))
            table[(m, speed)] = (float(np.mean(v[:, 1])), float(np.mean(v[:, 2])),
                                 float(np.sqrt(np.mean((v[:, 3] - v[:, 4]) ** 2)) / mean_var), len(v))
            if speed == args.plot_speed:
                light_curves[m] = v
        if speed == args.plot_speed:
            picks = [j for j in (7, 19, 31, 43) if j in shown]
            pictures = [(truths[j], shown[j], bicubic_shown[j], j) for j in picks]
        print(f"speed {speed:g}: " + ", ".join(
            f"{m} {table[(m, speed)][0]:.2f} dB, companion {table[(m, speed)][1]:.3f}, variable {table[(m, speed)][2]:.3f}"
            for m in methods), flush=True)

    lines = [
        f"Accuracy in time (bench/video_accuracy.py): the demo scene at r = {R} ({LR}² frames, {R * LR}² HR, "
        f"diffraction-limited K, the half-pixel raster), N = 4 phases at {RATE:g} frames/s, {args.frames} frames; a "
        "companion (FWHM 3 HR px) moving along x at SPEED HR px per frame and a star whose flux varies by ±80 % "
        "with a 0.4 s period (20 frames), both on dark sky; noise 1 % of the peak. Each output is scored against "
        "the truth at the time of its newest frame (what a viewer sees then), after the best global alignment. "
        "Cells: field PSNR (dB) / the companion's flux in a 3 HR px aperture at its true position, as a fraction "
        "of the truth's (1: all there; the window's smear moves light out) / the variable star's light curve, RMS "
        "error over its mean flux; means over the outputs (count in brackets).",
        "",
        "| method | " + " | ".join(f"speed {v:g} HR px/frame" for v in speeds) + " |",
        "|---|" + "---|" * len(speeds),
    ]
    for m in methods:
        lines.append(f"| {m} | " + " | ".join(
            f"{table[(m, v)][0]:.2f} / {table[(m, v)][1]:.3f} / {table[(m, v)][2]:.3f} ({table[(m, v)][3]})"
            for v in speeds) + " |")
    text = "\n".join(lines) + "\n"
    print()
    print(text)
    if args.out:
        with open(args.out, "w") as f:
            f.write(f"<!-- /usr/bin/python3 bench/video_accuracy.py --build {args.build} --frames {args.frames} "
                    f"--speeds {args.speeds} --plot-speed {args.plot_speed:g} -->\n" + text)
    if args.plot:
        truth_curve = light_curves["sliding"]
        panels = [
            {"title": f"Variable star: aperture flux against time (speed {args.plot_speed:g})",
             "x": {"label": "time of the output (s)"}, "y": {"label": "flux in the aperture (e-)"},
             # The methods first, so that each keeps its colour in every panel; the truth last.
             "series": [{"label": m, "x": list(light_curves[m][:, 0] / RATE), "y": list(light_curves[m][:, 3])}
                        for m in methods] +
                       [{"label": "truth", "x": list(truth_curve[:, 0] / RATE), "y": list(truth_curve[:, 4])}]},
            {"title": "Moving companion: flux in the aperture at its true position",
             "x": {"label": "speed (HR px per frame)"}, "y": {"label": "fraction of the truth's", "min": 0},
             "series": [{"label": m, "x": speeds, "y": [table[(m, v)][1] for v in speeds]} for m in methods]},
            {"title": "Whole field", "x": {"label": "speed (HR px per frame)"}, "y": {"label": "PSNR (dB)"},
             "series": [{"label": m, "x": speeds, "y": [table[(m, v)][0] for v in speeds]} for m in methods]},
        ]
        aosr.write_figure(args.plot, panels, columns=3, panel_width=560)
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
    shutil.rmtree(work, ignore_errors=True)


if __name__ == "__main__":
    main()
