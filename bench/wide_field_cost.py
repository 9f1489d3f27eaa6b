#!/usr/bin/env python3
"""What the field-varying model costs against one PSF (issue 31's target: at most 1.5x).

On the wide scene (data/scenes/wide-field-k.json, simulated once), each method reconstructs the same frames with
the guide star's PSF everywhere (psf_field 'none') and with the default field model (psf_field 'tiles': tiles
with local PSFs), alternately, `--reps` times on 1 and on 2 threads. Both choose their own regularisation as a
user's run does (Tikhonov's GCV, the linear output's leakage bound). TV runs a fixed number of iterations in the
field and in every tile (tolerances that never stop it), so that it compares the same iterations. Prints a
Markdown table of medians and minima, and checks that 1 and 2 threads give the same bytes.

  PYTHONPATH=build/python /usr/bin/python3 bench/wide_field_cost.py [--reps 11] [--methods tikhonov,linear,tv]
"""
import argparse
import os
import statistics
import sys
import tempfile
import time

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, os.path.join(ROOT, "build", "python"))
import aosr  # noqa: E402

TV_ITERATIONS = 60


def options(method):
    if method == "tv":  # the same iterations in the field and in every tile
        return {"tv_max_iterations": TV_ITERATIONS, "tv_absolute_tolerance": 1e-300,
                "tv_relative_tolerance": 1e-300, "tv_change_tolerance": 1e-300}
    return {}


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--reps", type=int, default=11)
    ap.add_argument("--methods", default="tikhonov,linear,tv")
    ap.add_argument("--dataset", default="", help="a simulated wide-field dataset (default: simulate the scene)")
    args = ap.parse_args()
    if args.dataset:
        ds = aosr.open_dataset(args.dataset)
    else:
        scene = aosr.read_json(os.path.join(ROOT, "data", "scenes", "wide-field-k.json"))
        ds = aosr.simulate(aosr.Scene(scene))
    print(f"wide scene: {ds.frames.shape[0]} frames of {ds.frames.shape[1]}^2 camera px, r = {ds.r}", flush=True)
    rows = []
    for method in args.methods.split(","):
        kw = options(method)
        reps = args.reps if method != "tv" else max(3, args.reps // 4)
        images = {}
        for threads in (1, 2):
            aosr.set_threads(threads)
            times = {"none": [], "tiles": []}
            for pf in times:  # warm: FFTW plans, the allocator's heap
                images[(pf, threads)] = aosr.reconstruct(ds, method, psf_field=pf, **kw).image
            for _ in range(reps):
                for pf in times:
                    t = time.perf_counter()
                    aosr.reconstruct(ds, method, psf_field=pf, **kw)
                    times[pf].append(time.perf_counter() - t)
            med = {pf: statistics.median(v) for pf, v in times.items()}
            low = {pf: min(v) for pf, v in times.items()}
            rows.append((method, threads, med, low, reps))
            print(f"{method} {threads} thread(s): none {med['none']:.3f} s, tiles {med['tiles']:.3f} s, "
                  f"{med['tiles'] / med['none']:.2f}x", flush=True)
        same = all(np.array_equal(images[(pf, 1)], images[(pf, 2)]) for pf in ("none", "tiles"))
        rows.append((method, "bytes", same, None, None))
    print()
    print("| method | threads | one PSF [s] | field by tiles [s] | tiles / one PSF (medians) | (minima) | runs |")
    print("|---|---|---|---|---|---|---|")
    for method, threads, med, low, reps in rows:
        if threads == "bytes":
            continue
        label = method if method != "tv" else f"tv ({TV_ITERATIONS} iterations)"
        print(f"| {label} | {threads} | {med['none']:.3f} | {med['tiles']:.3f} | {med['tiles'] / med['none']:.2f}x | "
              f"{low['tiles'] / low['none']:.2f}x | {reps} |")
    for method, threads, same, _, _ in rows:
        if threads == "bytes":
            print(f"\n{method}: 1 and 2 threads give the same bytes: {'yes' if same else 'NO'}")


if __name__ == "__main__":
    main()
