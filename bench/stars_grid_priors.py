#!/usr/bin/env python3
"""The stars PSF grid on the wide scene (issue 31's 2 % per node): how the prior that ties each node to the
nodes' mean (aosr.stars_psf's grid_variation, τ as a fraction of the peak) moves the nodes' errors against the
simulation's own PSF grid. One 3 x 3 fit per value (2-6 minutes each on the project's 2-core VM); per value the
5 x 5 table of the truth's nodes (RMS of the model interpolated there minus the true PSF over the central 8 x 8
camera px, % of the true peak), its worst and its median. bench/wide_field.py's node_errors does the scoring.

    PYTHONPATH=build/python /usr/bin/python3 bench/stars_grid_priors.py [--variations 0.3,1.0,0.15,0.07] [--stars N]

bench/results/wide_field.md ("Priors and quadratic weights", stop 51) quotes it.
"""
import argparse
import os
import sys
import time

import numpy as np

import aosr

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import wide_field  # noqa: E402  (bench/wide_field.py: node_errors)

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--variations", default="0.3,1.0,0.15,0.07", help="grid_variation values, comma-separated")
    ap.add_argument("--grid", type=int, default=3, help="stars grid nodes per axis")
    ap.add_argument("--stars", type=int, default=0,
                    help="the scene's star count instead of its own 1500 (a more crowded field), the rest unchanged")
    ap.add_argument("--degree", type=int, default=0,
                    help="grid_degree: the polynomial surface in position the nodes follow (0: tied to their mean)")
    ap.add_argument("--roughness", type=float, default=0.05, help="grid_roughness (with --degree >= 1)")
    ap.add_argument("--reject-extended", action="store_true", help="reject_extended: drop fits that are not point-like")
    args = ap.parse_args()
    scene = aosr.read_json(os.path.join(ROOT, "data", "scenes", "wide-field-k.json"))
    if args.stars:
        for o in scene["objects"]:
            if o["type"] == "stars":
                o["count"] = args.stars
    ds = aosr.simulate(aosr.Scene(scene))
    rows = []
    for v in (float(x) for x in args.variations.split(",")):
        t = time.time()
        st = aosr.stars_psf(ds, grid=(args.grid, args.grid), grid_variation=v, grid_degree=args.degree,
                            grid_roughness=args.roughness, reject_extended=args.reject_extended)
        core = np.array([e[0] for e in wide_field.node_errors(ds, st, ds.r)]) * 100
        side = int(round(np.sqrt(core.size)))
        print(f"grid_variation {v}, degree {args.degree}, roughness {args.roughness}, reject_extended {args.reject_extended}: {st['report']}, {time.time() - t:.0f} s", flush=True)
        print(np.array2string(core.reshape(side, side), precision=2), flush=True)
        rows.append((v, core.max(), np.median(core)))
    print(f"\n| {args.grid} x {args.grid} stars grid, grid_variation | worst node | median node |\n|---|---|---|")
    for v, worst, median in rows:
        print(f"| {v} | {worst:.2f} % | {median:.2f} % |")


if __name__ == "__main__":
    main()
