#!/usr/bin/python3
"""The MTF of each method for the paper's system: bench/results/mtf.md (issue 33, item 7).

For r = 2, 4 (and 8 with --r 2,4,8), the paper's scenes (data/scenes/paper-sim-r{r}.json: paper-8m, K band, camera
pixel lambda/D, N = 4 exposures on the classic raster, closed-loop Monte-Carlo AO with the diffractive Shack-Hartmann,
Gaussian noise of 1 % of the brightest noiseless pixel) with their USAF target replaced by a slanted edge (5 deg,
levels 100 and 1000 e- per HR pixel), under two conditions:
  * ao:     the scene as shipped (closed loop, Strehl ~0.85 at K);
  * seeing: the same atmosphere uncorrected: the analytic long-exposure model with the loop gain set to 0 (a copy of
            the paper-8m preset), so the frames are seeing-limited (Strehl ~0.02, FWHM ~6.6 lambda/D); the raster's
            dither is still applied (as a tip/tilt by the DM or the telescope would).
Each dataset is reconstructed with aosr.reconstruct's defaults (tikhonov: lambda by GCV; linear: automatic target
PSF; tv: automatic weight; map: capped at --map-iterations L-BFGS iterations as `aosr demo` does), plus drizzle and a
single-frame bicubic baseline (aosr.bicubic). Each output's slanted-edge MTF is read in the same central region,
clear of the trustworthy border (aosr.compare_mtf, the plain ISO 12233 LSF: smooth_tails=False, since the tail
smoothing removes a reconstruction's ringing), with the exact transfer of tikhonov (its model: the dataset's PSFs and
weights, lambda, gradient prior) and of the linear output (its effective PSF).

  * design: the `ao` scene with the N offsets `aosr design` returns for it (aosr.design: tip/tilt, 1 start, 15
            L-BFGS iterations, objective A over 1 AO realisation x 2 screens, judged on 3 fresh realisations and a sky
            4x finer than the HR grid, the default 0.2 dB threshold). Where the advice is the raster (the paper's
            K-band system at every r), the design file holds the raster and the case is the `ao` one: it is not
            rerun, the report says so with the expected gains. r = 8 has no design run (its objective is minutes
            per evaluation); --j adds the J-band scene (data/scenes/paper-sim-j-r2.json: camera pixel 1.76 lambda/D,
            analytic AO), where a design is advised, in both conditions.

Usage (from the repository root, after building the Python module):
    PYTHONPATH=build/python /usr/bin/python3 bench/mtf.py [--r 2,4] [--j] [--out bench/results/mtf.md]
Scratch: none (datasets in memory); the plots go beside the report (mtf/<condition>-r<r>.png).
"""
import argparse
import json
import os
import sys
import tempfile
import time

import numpy as np

import aosr
from results_file import write_keeping_analysis

METHODS = ("drizzle", "tikhonov", "linear", "tv", "map")


def scene_file(r, band):
    return aosr.data_path("scenes", f"paper-sim-j-r{r}.json" if band == "J" else f"paper-sim-r{r}.json")


def scene_dict(r, condition, preset_path, band="K", design_file=None):
    j = aosr.read_json(scene_file(r, band))
    j["name"] = f"mtf-{condition}-r{r}"
    if design_file:
        j["offsets"] = {"type": "design", "file": design_file}
    j["objects"] = [{"type": "slanted-edge", "angle_deg": 5.0, "low": 100.0, "high": 1000.0}]
    if condition == "seeing":
        j["telescope"] = preset_path
        j["ao"] = {"mode": "analytic"}
    return j


def curve_at(f, m, x):
    return float(np.interp(x, f, m)) if f[0] <= x <= f[-1] else float("nan")


def crossing(f, m, level=0.5):
    for i in range(1, len(f)):
        if m[i] <= level < m[i - 1]:
            return float(f[i - 1] + (f[i] - f[i - 1]) * (m[i - 1] - level) / (m[i - 1] - m[i]))
    return float("nan")


def fmt(v, digits=3):
    return "-" if v is None or not np.isfinite(v) else f"{v:.{digits}f}"


def design_for(r, band, path):
    """aosr.design of the scene (docstring: the design condition); the file at `path`, and its gain report."""
    t = time.time()
    d = aosr.design(scene_file(r, band), output=path, param="tiptilt", starts=1, iterations=15, realisations=1,
                    screens=2, validation_realisations=3, threads=2)
    g = d["gain"]
    grid = g.get("hr_grid_sky") or {}
    return {"advice": g["advice"], "db": g["db"], "stderr_db": g["stderr_db"], "hr_grid_db": grid.get("db"),
            "seconds": time.time() - t}


def run_case(r, condition, preset_path, map_iterations, plot_path, band="K", design_file=None):
    t0 = time.time()
    scene = aosr.scene_from_dict(scene_dict(r, condition, preset_path, band, design_file),
                                 source=scene_file(r, band))
    ds = aosr.simulate(scene)
    t_sim = time.time() - t0
    images, seconds = [("bicubic", aosr.bicubic(ds.frames_electrons()[0], r))], {"bicubic": 0.0}
    recs = []
    for m in METHODS:
        t = time.time()
        opts = {"map_max_iterations": map_iterations} if m == "map" else {}
        rec = aosr.reconstruct(ds, m, **opts)
        seconds[m] = time.time() - t
        recs.append(rec)
    hr = ds.truth.shape[0]
    border = int(ds.trustworthy_border_px * r)
    roi = (border + hr // 16, border, hr - 2 * border - hr // 8, hr - 2 * border)
    out = aosr.compare_mtf(images + recs + [("truth", ds.truth)], ds, roi=roi, r=r, smooth_tails=False,
                           plot=plot_path)
    rows = []
    nyq = 0.5 / r
    for o in out:
        row = {"label": o["label"], "status": o["exact_status"], "refusal": o["refusal"],
               "seconds": seconds.get(o["label"], float("nan"))}
        if o["measured"]:
            f, m = o["frequency"], o["mtf"]
            row.update(mtf50=o["mtf50"] if o["mtf50"] is not None else float("nan"), at_nyq=curve_at(f, m, nyq), at_2nyq=curve_at(f, m, 2 * nyq),
                       cnr=o["contrast_to_noise"])
        if o["exact"] is not None:
            fe, me = o["exact"]["frequency"], o["exact"]["mtf"]
            row.update(exact_mtf50=crossing(fe, me), exact_at_nyq=curve_at(fe, me, nyq),
                       exact_at_2nyq=curve_at(fe, me, 2 * nyq))
            if o["measured"]:
                n = len(me)
                row["worst_gap"] = float(np.max(np.abs(np.asarray(o["mtf"][:n]) - me)))
        rows.append(row)
    notes = [f"{rec.method}: regularisation {rec.regularisation:.4g}; {rec.summary['message']}"
             for rec in recs if rec.method in ("tikhonov", "tv", "map")]
    return {"r": r, "band": band, "condition": condition, "roi": roi, "simulate_seconds": t_sim, "notes": notes,
            "total_seconds": time.time() - t0, "rows": rows}


def markdown(results, args, wall):
    lines = ["# MTF of each method for the paper's system (issue 33, item 7)", "",
             "Made by `PYTHONPATH=build/python /usr/bin/python3 bench/mtf.py --r " + args.r + (" --j" if args.j else "") +
             f" --map-iterations {args.map_iterations}` ({wall:.0f} s wall on the 2-core development VM, shared with "
             "other builds). The method, the scenes and the conditions are in the script's docstring; in short: "
             "the paper-sim scenes with a 5 deg slanted edge (levels 100 and 1000 e- per HR px, noise 1 % of the "
             "brightest pixel), N = 4 on the classic raster, `ao` = the closed-loop Monte-Carlo AO as shipped, "
             "`seeing` = the same atmosphere uncorrected (analytic model, loop gain 0), `design` = the `ao` scene "
             "with the offsets `aosr design` returns for it (not rerun where that is the raster). Each output is "
             "read in the "
             "same central region by the slanted edge (plain ISO 12233 LSF); frequencies in cycles per HR pixel; "
             "the camera's Nyquist is 1/(2r). `exact`: the method's exact transfer (include/aosr/solvers/"
             "linear_transfer.hpp) along the edge normal, times the HR pixel box; `gap`: the largest |edge - exact| "
             "up to the HR Nyquist (the edge's noise: the exact curve is the expectation, the edge one noise draw; the "
             "noise-free tests read the exact curves to 0.0015). MTF50 is the edge method's (found up to 1.5 "
             "cycles/px, so past the HR Nyquist 0.5 for the sharpest outputs). TV and MAP are signal-dependent: their curve holds at this contrast and noise "
             "only.", ""]
    for res in results:
        r, cond, band = res["r"], res["condition"], res.get("band", "K")
        name = f"r = {r}, {cond}" + (", J band (paper-sim-j-r2)" if band == "J" else "")
        if "design" in res:
            g = res["design"]
            line = (f"`aosr design` ({g['seconds']:.1f} s): expected gain {g['db']:+.2f} +- {g['stderr_db'] or 0:.2f} dB "
                    f"on a sky 4x finer than the HR grid ({g['hr_grid_db']:+.2f} dB on the HR grid's own sky); advice: "
                    f"{g['advice']}.")
            if "rows" not in res:
                lines += [f"## {name}", "", line + " The design file holds the raster, so this case is the `ao` one "
                          "above (not rerun).", ""]
                continue
        lines += [f"## {name}", "",
                  f"Region (x0, y0, w, h) = {tuple(res['roi'])} HR px; simulation {res['simulate_seconds']:.1f} s, "
                  f"case {res['total_seconds']:.1f} s. Plot: `mtf/{res.get('plot', f'{cond}-r{r}.png')}`."
                  + (" " + line if "design" in res else ""), "",
                  "| output | MTF50 | MTF at 1/(2r) | MTF at 1/r | exact MTF50 | exact at 1/(2r) | exact at 1/r | gap | "
                  "CNR | seconds | exact |",
                  "|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---|"]
        for w in res["rows"]:
            if w.get("refusal"):
                lines.append(f"| {w['label']} | no usable edge: {w['refusal']} | | | | | | | | | {w['status']} |")
                continue
            lines.append("| " + " | ".join([
                w["label"], fmt(w.get("mtf50")), fmt(w.get("at_nyq")), fmt(w.get("at_2nyq")),
                fmt(w.get("exact_mtf50")), fmt(w.get("exact_at_nyq")), fmt(w.get("exact_at_2nyq")),
                fmt(w.get("worst_gap")), fmt(w.get("cnr"), 0), fmt(w.get("seconds"), 2), w["status"]]) + " |")
        lines.append("")
        lines += [f"- {n}" for n in res["notes"]]
        lines.append("")
    return "\n".join(lines)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--r", default="2,4", help="comma-separated r values (2,4,8)")
    ap.add_argument("--conditions", default="ao,seeing,design")
    ap.add_argument("--j", action="store_true", help="also the J-band scene paper-sim-j-r2 (ao and design)")
    ap.add_argument("--map-iterations", type=int, default=40)
    ap.add_argument("--out", default="bench/results/mtf.md")
    ap.add_argument("--json", default="", help="also write the numbers as JSON")
    args = ap.parse_args()
    t0 = time.time()
    plots = os.path.join(os.path.dirname(args.out) or ".", "mtf")
    os.makedirs(plots, exist_ok=True)
    with tempfile.TemporaryDirectory() as tmp:
        preset = aosr.read_json(aosr.data_path("telescopes", "paper-8m.json"))
        preset["name"] = "paper-8m-seeing"
        preset["ao"]["loop"]["gain"] = 0.0
        preset_path = os.path.join(tmp, "paper-8m-seeing.json")
        with open(preset_path, "w") as f:
            json.dump(preset, f)
        results = []
        cases = [(r, cond, "K") for r in [int(x) for x in args.r.split(",")] for cond in args.conditions.split(",")]
        if args.j:
            cases += [(2, cond, "J") for cond in ("ao", "design")]
        for r, cond, band in cases:
            plot = f"{cond}-r{r}{'-j' if band == 'J' else ''}.png"
            design = None
            if cond == "design":
                if r >= 8:
                    continue
                path = os.path.join(tmp, f"design-{band}-r{r}.json")
                design = design_for(r, band, path)
                print(f"r = {r} {band} design: {design}", file=sys.stderr)
                if design["advice"] != "design":
                    results.append({"r": r, "band": band, "condition": cond, "design": design})
                    continue
            res = run_case(r, "ao" if cond == "design" else cond, preset_path, args.map_iterations,
                           os.path.join(plots, plot), band, path if design else None)
            res["condition"], res["plot"] = cond, plot
            if design:
                res["design"] = design
            print(f"r = {r} {band} {cond}: {res['total_seconds']:.1f} s", file=sys.stderr)
            for w in res["rows"]:
                print(f"  {w['label']:10s} MTF50 {fmt(w.get('mtf50'))} at 1/(2r) {fmt(w.get('at_nyq'))} "
                      f"exact {fmt(w.get('exact_at_nyq'))} gap {fmt(w.get('worst_gap'))} {w['status']}",
                      file=sys.stderr)
            results.append(res)
    write_keeping_analysis(args.out, markdown(results, args, time.time() - t0) + "\n")
    if args.json:
        with open(args.json, "w") as f:
            json.dump(results, f, indent=1, default=float)
    print(f"wrote {args.out} ({time.time() - t0:.0f} s)", file=sys.stderr)


if __name__ == "__main__":
    main()
