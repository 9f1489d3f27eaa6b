#!/usr/bin/python3
"""Where each closed-loop frame's image lands against the nominal model: bench/results/psf_offsets.md.

Issue 23's remaining gap (`--model-psfs nominal` against the oracle, scored unaligned) is a per-frame position
error of the simulated long-exposure PSFs against the nominal (analytic-AO) ones. This bench measures it as a
function of the wavefront sensor model and of the telescope time simulated per exposure, to say whether it is an
artefact of the short Monte-Carlo stretch (it would then average down as 1/sqrt(T)) or a property of the loop.

The reconstructions: `aosr reconstruct -m tikhonov / tv / map` on paper-sim-r2 and -r4 with the oracle and with
`--model-psfs nominal`, before (one realisation, flat reference slopes) and with the defaults.

For each sensor (ideal, geometric, diffractive Shack-Hartmann; the last with the offsets' reference slopes taken on a
flat wavefront and calibrated on sky, `ao.offset_calibration`), one realisation per exposure or the antithetic pair
(`ao.antithetic`, the default), and exposure time T (`ao.time_per_frame_s`), the
paper's r = 2 scene (data/scenes/paper-sim-r2.json: paper-8m, K band, N = 4 raster of +-0.25 camera px) is
simulated with several atmosphere seeds. Per frame i, the offset d_i of the oracle PSF (psfs.fits) against the
nominal one (nominal_psfs.fits) is the global sub-pixel shift that best aligns them (`aosr.compare_images_aligned`,
upsampled cross-correlation then refinement; both normalised to the oracle's peak). Reported, in HR px (0.5 lambda/D):
  * common: |mean_i d_i| over the 4 frames, what no registration from the frames can see;
  * differential: RMS over frames of d_i - mean d, what `--offsets estimate` can measure;
  * gain: the least-squares slope of d_i against the commanded offsets c_i (0 = the image lands where commanded;
    0.1 = the loop moves the image 10 % further than commanded).
Each cell is the RMS over seeds (the gain: the mean).

Usage (from the repository root, after building build/aosr and the Python module):
    PYTHONPATH=build/python /usr/bin/python3 bench/psf_offsets.py [--seeds 3] [--out bench/results/psf_offsets.md]
Scratch: build/psf_offsets/. Two simulations at a time, one thread each.
"""
import argparse
import concurrent.futures as cf
import json
import math
import os
import subprocess
import sys
import time

import numpy as np
from astropy.io import fits

import aosr

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), ".."))
AOSR = os.path.join(ROOT, "build", "aosr")
SCRATCH = os.path.join(ROOT, "build", "psf_offsets")
SCENE = os.path.join(ROOT, "data", "scenes", "paper-sim-r2.json")
# (sensor, ao.offset_calibration, ao.antithetic): one realisation per exposure for every sensor (the linear
# sensors need no calibration: their tilt gain is 1), the diffractive Shack-Hartmann with and without the
# offsets' calibration, then the default (calibrated, antithetic pair) for the geometric and diffractive SH.
CASES = [("ideal", "on-sky", False), ("geometric", "on-sky", False), ("diffractive", "flat", False),
         ("diffractive", "on-sky", False), ("geometric", "on-sky", True), ("diffractive", "on-sky", True)]
TIMES = [0.1, 0.4, 1.6]


EXTRA = []  # --set overrides for every simulation (from the command line)


def simulate(sensor, calibration, antithetic, t, seed):
    out = os.path.join(SCRATCH, f"{sensor}-{calibration}-{antithetic}-{t}-{seed}")
    # A PSF every 2nd loop frame above 0.1 s: the long exposure's average is unchanged to sampling noise and the
    # 1.6 s runs stay ~10 s.
    every = 1 if t <= 0.1 else 2
    cmd = [AOSR, "simulate", SCENE, "-o", out, "--threads", "1", "--set", f"ao.sensor={sensor}",
           "--set", f"ao.time_per_frame_s={t}", "--set", f"ao.seed={seed}", "--set", f"ao.psf_every_steps={every}", "--set", f"ao.offset_calibration={calibration}",
           "--set", f"ao.antithetic={'true' if antithetic else 'false'}"]
    for e in EXTRA:
        cmd += ["--set", e]
    subprocess.run(cmd, check=True, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    return out


def psnr(folder, method, nominal):
    """Raw (unaligned) PSNR of `aosr reconstruct -m method` against the truth, with the oracle or nominal PSFs."""
    out = os.path.join(folder, f"rec-{method}-{'nominal' if nominal else 'oracle'}.fits")
    cmd = [AOSR, "reconstruct", folder, "-m", method, "-o", out, "--json", "--threads", "1"]
    if nominal:
        cmd += ["--model-psfs", "nominal"]
    p = subprocess.run(cmd, check=True, capture_output=True, text=True)
    return json.loads(p.stdout)["against_truth"]["psnr_db"]


def simulate_scene(scene, cal, anti, seed):
    """paper-sim-<scene> with the given offset calibration, antithetic flag and atmosphere seed (None: the scene's)."""
    out = os.path.join(SCRATCH, f"recon-{scene}-{cal}-{anti}-{seed}")
    cmd = [AOSR, "simulate", os.path.join(ROOT, "data", "scenes", f"paper-sim-{scene}.json"), "-o", out, "--threads",
           "1", "--set", f"ao.offset_calibration={cal}", "--set", f"ao.antithetic={'true' if anti else 'false'}"]
    if seed is not None:
        cmd += ["--set", f"ao.seed={seed}"]
    subprocess.run(cmd, check=True, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    return out


def gap_job(job):
    """(scene, calibration, antithetic, seed or None, method) -> nominal minus oracle unaligned PSNR [dB]."""
    scene, cal, anti, seed, method = job
    out = os.path.join(SCRATCH, f"recon-{scene}-{cal}-{anti}-{seed}")
    return psnr(out, method, True) - psnr(out, method, False)


def offsets(folder):
    manifest = json.load(open(os.path.join(folder, "manifest.json")))
    oracle = fits.getdata(os.path.join(folder, "psfs.fits")).astype(float)
    nominal = fits.getdata(os.path.join(folder, "nominal_psfs.fits")).astype(float)
    d = []
    for o, n in zip(oracle, nominal):
        r = aosr.compare_images_aligned(o / o.max(), n / o.max())
        # The offset of the second image against the first: minus the oracle's against the nominal.
        d.append([-r["offset_px"]["dy"], -r["offset_px"]["dx"]])
    c = np.array([[o["shift_px"][0], o["shift_px"][1]] for o in manifest["offsets"]]) * manifest["r"]
    return np.array(d), c


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--seeds", type=int, default=3)
    ap.add_argument("--out", default=None)
    ap.add_argument("--set", action="append", default=[], help="a scene override for every simulation, KEY=VALUE")
    args = ap.parse_args()
    EXTRA.extend(args.set)
    if args.seeds < 1:
        sys.exit("psf_offsets.py: --seeds must be >= 1")
    os.makedirs(SCRATCH, exist_ok=True)
    t0 = time.time()
    jobs = [(s, cal, anti, t, seed) for s, cal, anti in CASES for t in TIMES for seed in range(1, args.seeds + 1)]
    with cf.ThreadPoolExecutor(max_workers=2) as pool:
        folders = dict(zip(jobs, pool.map(lambda j: simulate(*j), jobs)))
    rows = []
    raw = {}
    for s, cal, anti in CASES:
        for t in TIMES:
            common, diff, gain, per_frame = [], [], [], []
            for seed in range(1, args.seeds + 1):
                d, c = offsets(folders[(s, cal, anti, t, seed)])
                raw[f"{s}/{cal}/{anti}/{t}/{seed}"] = d.tolist()
                m = d.mean(axis=0)
                common.append(float(np.hypot(*m)))
                diff.append(float(np.sqrt(((d - m) ** 2).sum(axis=1).mean())))
                cc = c - c.mean(axis=0)
                gain.append(float((cc * (d - m)).sum() / (cc * cc).sum()))
                per_frame.append(float(np.sqrt((d ** 2).sum(axis=1).mean())))
            rms = lambda v: math.sqrt(sum(x * x for x in v) / len(v))
            rows.append((s, cal, anti, t, rms(per_frame), rms(common), rms(diff), sum(gain) / len(gain), min(gain), max(gain)))
    # Reconstructions: nominal minus oracle, unaligned, on the shipped scenes (their own seed) with one
    # uncalibrated realisation per exposure and with the defaults; TV also on atmosphere seeds 1-3 at r = 2.
    # Sequential per scene so the two workers never simulate the same folder.
    gap_jobs = [(sc, cal, anti, None, m) for cal, anti in (("flat", False), ("on-sky", True)) for sc in ("r2", "r4")
                for m in ("tikhonov", "tv", "map")]
    gap_jobs += [("r2", "on-sky", True, seed, "tv") for seed in range(1, args.seeds + 1)]
    folders_needed = sorted({(sc, cal, anti, seed) for sc, cal, anti, seed, _ in gap_jobs}, key=str)
    with cf.ThreadPoolExecutor(max_workers=2) as pool:
        list(pool.map(lambda f: simulate_scene(*f), folders_needed))
        gaps = dict(zip(gap_jobs, pool.map(gap_job, gap_jobs)))
    elapsed = time.time() - t0
    os.makedirs(SCRATCH, exist_ok=True)
    json.dump(raw, open(os.path.join(SCRATCH, "results.json"), "w"), indent=1)

    lines = [
        "<!-- produced by: PYTHONPATH=build/python /usr/bin/python3 bench/psf_offsets.py"
        + (f" --seeds {args.seeds}" if args.seeds != 3 else "") + " --out bench/results/psf_offsets.md -->",
        "# Where each closed-loop frame's image lands against the nominal model",
        "",
        f"Command: `PYTHONPATH=build/python /usr/bin/python3 bench/psf_offsets.py --out bench/results/psf_offsets.md` "
        f"({elapsed:.0f} s; raw offsets in build/psf_offsets/results.json). The paper's r = 2 scene "
        "(data/scenes/paper-sim-r2.json: paper-8m, K band, camera pixel lambda/D, N = 4 raster of +-0.25 camera px = "
        "+-0.5 HR px) with the closed-loop Monte-Carlo, per sensor model and telescope time per exposure T, "
        f"atmosphere seeds 1-{args.seeds}. Offset d_i: the sub-pixel shift that best aligns frame i's oracle PSF "
        "(psfs.fits) with its nominal one (nominal_psfs.fits, the analytic-AO model at the commanded offset), HR px "
        "(1 HR px = 0.5 lambda/D = 28.4 mas). Columns: RMS over frames and seeds of |d_i|; the common part "
        "|mean_i d_i| (RMS over seeds), which no registration from the frames can measure; the differential part "
        "(RMS of d_i - mean d), which `--offsets estimate` can; the gain, the slope of d_i against the commanded "
        "offsets (mean, min..max over seeds).",
        "",
        "| sensor | offset calibration | antithetic pair | T [s] | per frame [HR px] | common [HR px] | differential [HR px] | gain (mean) | gain (min..max) |",
        "|---|---|---|---:|---:|---:|---:|---:|---|",
    ]
    for s, cal, anti, t, pf, cm, df, g, gmin, gmax in rows:
        lines.append(f"| {s} | {cal} | {'yes' if anti else 'no'} | {t:g} | {pf:.3f} | {cm:.3f} | {df:.3f} | {g:+.3f} | {gmin:+.3f}..{gmax:+.3f} |")
    by = {(s, cal, anti, t): (pf, cm, df, g, gmin, gmax) for s, cal, anti, t, pf, cm, df, g, gmin, gmax in rows}
    flat = [by[("diffractive", "flat", False, t)] for t in TIMES]
    onsky = [by[("diffractive", "on-sky", False, t)] for t in TIMES]
    pair = [by[("diffractive", "on-sky", True, t)] for t in TIMES]
    ideal = [by[("ideal", "on-sky", False, t)] for t in TIMES]
    lines += [
        "",
        "Nominal model minus oracle, unaligned PSNR as `aosr reconstruct` scores it (dB; the shipped scenes' own "
        "atmosphere seed; issue 23's target: within 0.3 dB):",
        "",
        "| scene | offsets | tikhonov | tv | map |",
        "|---|---|---:|---:|---:|",
    ]
    for cal, anti, label in (("flat", False, "one realisation, flat reference slopes (before)"),
                             ("on-sky", True, "defaults: on-sky calibration, antithetic pair")):
        for sc in ("r2", "r4"):
            lines.append(f"| paper-sim-{sc} | {label} | " +
                         " | ".join(f"{gaps[(sc, cal, anti, None, m)]:+.2f}" for m in ("tikhonov", "tv", "map")) + " |")
    lines.append("")
    lines.append("TV on paper-sim-r2 with the defaults and atmosphere seeds " +
                 ", ".join(f"{seed}: {gaps[('r2', 'on-sky', True, seed, 'tv')]:+.2f} dB" for seed in range(1, args.seeds + 1)) + ".")
    lines += [
        "",
        "Reading the table.",
        f"* **A bias, removed by calibrating the offsets.** With reference slopes taken on a flat wavefront the "
        f"diffractive Shack-Hartmann moves every image {min(r[4] for r in flat):+.2f} to {max(r[5] for r in flat):+.2f} "
        "of its commanded offset further out (the gain column), whatever T: its closed-loop tip/tilt gain is ~0.87 "
        "(turbulence-broadened spots whose wings wrap in the 16 px lenslet field), so the loop holds ~1/0.87 of the "
        "offset's tilt. `ao.offset_calibration: on-sky` (the default) measures that gain at the operating point and "
        f"rescales the offsets: gain {min(r[4] for r in onsky):+.2f} to {max(r[5] for r in onsky):+.2f}, like the "
        "linear sensors (tests/ao/closed_loop_physics_test.cpp, OffsetsLandWhereCommandedWithOnSkyCalibration: "
        "0.984-0.999 of the commanded shift against 1.13-1.16 flat).",
        f"* **A random tilt per stretch, removed by the antithetic pair.** One realisation leaves each exposure "
        f"displaced by a random {onsky[0][0]:.3f} HR px (RMS) with the diffractive SH and {by[('geometric', 'on-sky', False, 0.1)][0]:.3f} "
        "with the geometric one at T = 0.1 s, and it does not average down by T = 1.6 s "
        f"({onsky[2][0]:.3f}; the SH senses the mean gradient over its lenslets, the image core follows the "
        "least-squares tilt, and their difference comes from the largest turbulence scales, which change over "
        f"seconds); the ideal sensor's averages down ({ideal[0][0]:.3f} -> {ideal[2][0]:.3f}). A real integration of "
        "minutes would average it away; the simulated stretch does not. The tilt is odd in the atmosphere, so "
        "`ao.antithetic: true` (the default: the loop run on the atmosphere and on its negation, each exposure's "
        f"PSF averaged over the pair) cancels it: {pair[0][0]:.3f} HR px per frame and a common part of "
        f"{max(r[1] for r in pair):.3f} HR px, with a small systematic gain of {min(r[3] for r in pair):+.3f} "
        "(the image lands ~2 % short of the commanded offset against the analytic model; 0.005 lambda/D).",
    ]
    text = "\n".join(lines) + "\n"
    if args.out:
        tmp = args.out + ".tmp"
        with open(tmp, "w") as f:
            f.write(text)
        os.replace(tmp, args.out)
    print(text)


if __name__ == "__main__":
    main()
