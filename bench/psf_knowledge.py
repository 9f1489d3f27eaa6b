#!/usr/bin/python3
"""How well the PSF must be known (issue 23 item 4): bench/results/psf_knowledge.md.

The paper's system (data/scenes/paper-sim-r2.json and -r4.json: paper-8m, closed-loop Monte-Carlo AO with the
diffractive Shack-Hartmann, N = 4 raster, 128 px frames) at K, H and J band, r = 2 and 4, observing
  * the USAF target with the paper's noise (Gaussian, 1 % of the brightest noiseless pixel): every method;
  * the crowded-stars field (data/scenes/crowded-stars.json's 400 stars, photometry and near-IR detector) seen
    through the same closed-loop system: the linear (target-PSF) output's photometric bias.
Each dataset is reconstructed with
  * the oracle PSFs (the simulation's own per-frame long exposures: no --model-psfs),
  * the nominal model (--model-psfs nominal: NominalPsfs(scene), the same scene with analytic AO),
  * nominal models wrong in one thing at a time: NominalPsfs of a modified scene, obtained as a user would (the
    modified scene simulated with "ao": {"mode": "analytic"}, its psfs.fits passed as --model-psfs FILE),
  * and data whose truth holds something the model does not know (the model is the unmodified scene's nominal
    file): a 50 nm RMS non-common-path aberration (scene static_aberrations: science path only), a DM whose
    stroke is 0.9 or 1.1 times the commanded one (scene ao.dm_gain), a noisy Shack-Hartmann (photon and read
    noise) on a guide star of R = 6, 8, 10, 12 (the preset's WFS is noiseless and the analytic model has none). Those datasets also get their own oracle
    row, and every difference is taken against the oracle of the same data.
Scores are `aosr reconstruct`'s (the dataset's trustworthy border left out): PSNR/SSIM after the best global
sub-pixel alignment, the offset itself (HR px and mas), and the raw PSNR; stars: `aosr evaluate --manifest`
(star_metrics.hpp: aperture of 1.5 camera px against the same aperture on the truth image, annulus background),
median signed flux error of the 50 brightest stars.

Bands: K 2.2, H 1.65, J 1.25 um with the camera pixel at lambda/D in each band (a camera matched to the band, as
near-IR imagers with selectable plate scales are), so the sampling in lambda/D is the paper's everywhere and what
changes is the AO correction (lower Strehl at shorter wavelengths); the atmosphere (r0 = 15 cm at 550 nm) and the
R-band Shack-Hartmann are the preset's. Star field: photometry band = science band, sky 13.0 / 14.4 / 16.0
mag/arcsec^2 at K / H / J.

Usage (from the repository root, after building build/aosr):
    /usr/bin/python3 bench/psf_knowledge.py [--quick] [--out bench/results/psf_knowledge.md]
--quick: K band only, no MAP (about a quarter of the full run's CPU). The full run: 953 s of CPU in the aosr
processes (so ~8 min on 2 idle cores), 2401 s wall on the shared 2-core VM at load ~11 (2026-11-27). Two aosr
processes at a time, one thread each. Scratch: build/psf_knowledge/ (raw numbers in results.json there).
"""
import argparse
import concurrent.futures as cf
import copy
import json
import math
import os
import resource
import statistics
import subprocess
import sys
import time

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), ".."))
AOSR = os.path.join(ROOT, "build", "aosr")
SCRATCH = os.path.join(ROOT, "build", "psf_knowledge")
PRESET = json.load(open(os.path.join(ROOT, "data", "telescopes", "paper-8m.json")))
CROWDED = json.load(open(os.path.join(ROOT, "data", "scenes", "crowded-stars.json")))
BANDS = {"K": 2.2e-6, "H": 1.65e-6, "J": 1.25e-6}
SKY_MAG = {"K": 13.0, "H": 14.4, "J": 16.0}
STARS_MEASURED = 50

# The non-common-path aberration: Noll 4..11 (defocus, astigmatism, coma, trefoil, spherical; no tip/tilt, which
# is a shift the aligned scores would remove) with fixed relative weights, scaled to 50 nm RMS in total
# (orthonormal Zernikes: the RMS is the root sum of squares).
NCPA_WEIGHTS = {4: 1.0, 5: -0.7, 6: 0.5, 7: 0.6, 8: -0.4, 9: 0.3, 10: -0.3, 11: 0.25}
NCPA_RMS_NM = 50.0


def ncpa_terms():
    norm = sum(w * w for w in NCPA_WEIGHTS.values()) ** 0.5
    return [{"noll": j, "rms_nm": NCPA_RMS_NM * w / norm} for j, w in NCPA_WEIGHTS.items()]


def scale_layers(wind):
    def f(tel):
        for layer in tel["atmosphere"]["layers"]:
            layer["wind_speed_mps"] *= wind
    return f


def set_path(path, value, scale=False):
    def f(tel):
        node = tel
        for k in path[:-1]:
            node = node[k]
        node[path[-1]] = node[path[-1]] * value if scale else node[path[-1]] + value
    return f


# What the truth holds (a patch of the scene), keyed by name.
TRUTHS = {
    "base": lambda s: None,
    "ncpa": lambda s: s.__setitem__("static_aberrations", ncpa_terms()),
    "dm0.9": lambda s: s["ao"].__setitem__("dm_gain", 0.9),
    "dm1.1": lambda s: s["ao"].__setitem__("dm_gain", 1.1),
}
# The guide star's magnitude acts only through the Shack-Hartmann's noise, which the paper-8m preset leaves off
# (photon_noise false, no read noise): these truths switch it on (photon noise, 1 e- read noise per spot pixel)
# at R = 6, 8, 10 (the preset's 8 +- 2 mag) and 12. Two models per magnitude: the noiseless nominal model (the
# base scene's: a model that ignores the guide star's noise), and the noisy scene's own nominal model, whose
# analytic noise term is measured through the sensor and reconstructor (TelescopePreset::ToAnalyticAo,
# MeasureWfsNoiseRad2): a model that knows the magnitude.
GS_MAGNITUDES = [6, 8, 10, 12]


def noisy_guide_star(mag):
    def f(s):
        s["telescope"]["ao"]["wfs"].update(photon_noise=True, read_noise_e=1.0, guide_star_magnitude=float(mag))
    return f


for _m in GS_MAGNITUDES:
    TRUTHS["gs%d" % _m] = noisy_guide_star(_m)

# The rows: (key, label, truth, model). model is "oracle" (no --model-psfs), "cli:VALUE" (--model-psfs VALUE as
# given, e.g. cli:nominal), "base-nominal" (the unmodified scene's nominal_psfs.fits of the base truth), or a
# function patching the telescope preset of the model's scene (NominalPsfs of the modified scene).
# The stars row (--model-psfs stars: empirical PSFs from the point sources in the frames, solvers/stars_psf.hpp)
# runs on the star field only: the USAF target has no stars to build it from.
ROWS = [
    ("oracle", "oracle PSFs (the simulation's own)", "base", "oracle"),
    ("nominal", "nominal model (--model-psfs nominal)", "base", "cli:nominal"),
    ("stars", "empirical PSFs from the field's stars (--model-psfs stars; star field only)", "base", "cli:stars"),
    ("r0-30", "model r0 -30 % (0.105 m)", "base", set_path(["atmosphere", "r0_m"], 0.7, True)),
    ("r0+30", "model r0 +30 % (0.195 m)", "base", set_path(["atmosphere", "r0_m"], 1.3, True)),
    ("wind2", "model wind x2 (every layer)", "base", scale_layers(2.0)),
    ("gain0.5", "model loop gain x0.5 (0.175)", "base", set_path(["ao", "loop", "gain"], 0.5, True)),
    ("gain1.5", "model loop gain x1.5 (0.525)", "base", set_path(["ao", "loop", "gain"], 1.5, True)),
    ("ncpa-oracle", "truth with 50 nm NCPA: oracle PSFs", "ncpa", "oracle"),
    ("ncpa", "truth with 50 nm NCPA: nominal model without it", "ncpa", "base-nominal"),
    ("dm0.9-oracle", "truth DM gain 0.9: oracle PSFs", "dm0.9", "oracle"),
    ("dm0.9", "truth DM gain 0.9: nominal model (gain 1)", "dm0.9", "base-nominal"),
    ("dm1.1-oracle", "truth DM gain 1.1: oracle PSFs", "dm1.1", "oracle"),
    ("dm1.1", "truth DM gain 1.1: nominal model (gain 1)", "dm1.1", "base-nominal"),
]
for _m in GS_MAGNITUDES:
    ROWS += [("gs%d-oracle" % _m, "truth WFS noise, guide star R = %d: oracle PSFs" % _m, "gs%d" % _m, "oracle"),
             ("gs%d" % _m, "truth WFS noise, guide star R = %d: nominal model (noiseless WFS)" % _m, "gs%d" % _m,
              "base-nominal"),
             ("gs%d-noise" % _m, "truth WFS noise, guide star R = %d: nominal model with its noise term" % _m,
              "gs%d" % _m, "cli:nominal")]


def run_json(args):
    p = subprocess.run([AOSR] + [str(a) for a in args] + ["--json", "--threads", "1"], capture_output=True, text=True)
    if p.returncode != 0:
        raise RuntimeError("aosr %s failed (%d): %s" % (" ".join(map(str, args)), p.returncode, p.stderr[-600:]))
    return json.loads(p.stdout)


def telescope(band):
    tel = copy.deepcopy(PRESET)
    tel["name"] = "paper-8m-" + band
    tel["science"] = {"wavelength_m": BANDS[band], "camera_pixel_lambda_over_d": 1.0}
    return tel


def scene(target, band, r):
    s = json.load(open(os.path.join(ROOT, "data", "scenes", "paper-sim-r%d.json" % r)))
    s["name"] = "psfk-%s-%s-r%d" % (target, band, r)
    s["telescope"] = telescope(band)
    if target == "stars":
        s["objects"] = copy.deepcopy(CROWDED["objects"])
        s["photometry"] = dict(CROWDED["photometry"], band=band)
        s["detector"] = dict(CROWDED["detector"], sky_mag_per_arcsec2=SKY_MAG[band])
        s["psf"] = copy.deepcopy(CROWDED["psf"])
    return s


def simulate(path, s, out):
    json.dump(s, open(path, "w"), indent=1)
    return run_json(["simulate", path, "-o", out])


def cell_dir(target, band, r):
    return os.path.join(SCRATCH, "%s-%s-r%d" % (target, band, r))


def truth_job(target, band, r, truth):
    d = cell_dir(target, band, r)
    s = scene(target, band, r)
    TRUTHS[truth](s)
    out = os.path.join(d, "truth-" + truth)
    j = simulate(os.path.join(d, "truth-%s.json" % truth), s, out)
    return (target, band, r, truth), {"dir": out, "strehl": statistics.mean(j["strehl"])}


def model_job(target, band, r, key, patch):
    """NominalPsfs of the scene with the telescope patched: the scene simulated with analytic AO (its psfs.fits is
    NominalPsfs of the closed-loop scene by definition, pipeline.hpp)."""
    d = cell_dir(target, band, r)
    s = scene(target, band, r)
    if patch is not None:
        patch(s["telescope"])
    s["ao"] = {"mode": "analytic"}
    out = os.path.join(d, "model-" + key)
    simulate(os.path.join(d, "model-%s.json" % key), s, out)
    return (target, band, r, key), os.path.join(out, "psfs.fits")


def model_args(target, band, r, row, models, truths):
    key, _, _, model = row
    if model == "oracle":
        return []
    if isinstance(model, str) and model.startswith("cli:"):
        return ["--model-psfs", model[4:]]
    if model == "base-nominal":
        return ["--model-psfs", os.path.join(truths[(target, band, r, "base")]["dir"], "nominal_psfs.fits")]
    return ["--model-psfs", models[(target, band, r, key)]]


def recon_job(target, band, r, row, method, margs, truth_dir):
    key = row[0]
    out = os.path.join(cell_dir(target, band, r), "rec-%s-%s.fits" % (key, method))
    t = time.time()
    j = run_json(["reconstruct", truth_dir, "-m", method, "-o", out] + margs)
    res = {"seconds": time.time() - t}
    a = j["against_truth"]
    res.update(psnr=a["psnr_db"], ssim=a["ssim"], psnr_al=a["aligned"]["psnr_db"], ssim_al=a["aligned"]["ssim"],
               dy=a["offset_hr_px"]["dy"], dx=a["offset_hr_px"]["dx"], dy_mas=a["offset_mas"]["dy"],
               dx_mas=a["offset_mas"]["dx"])
    if target == "stars":
        e = run_json(["evaluate", "--manifest", truth_dir, "--estimate", out, "--stars", STARS_MEASURED,
                      "--aperture", 1.5 * r])
        errs = [s["flux_error"] for s in e["stars"]["brightest"]]
        res.update(bias=statistics.median(errs), stars=len(errs), pos_rms=e["stars"]["rms_position_error_hr_px"])
    os.remove(out)
    return (target, band, r, key, method), res


def compare_fits(a, b):
    from astropy.io import fits
    import numpy as np
    x = fits.getdata(a).astype(float)
    y = fits.getdata(b).astype(float)
    return float(np.abs(x - y).max() / np.abs(x).max())


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--quick", action="store_true")
    ap.add_argument("--out", default=None)
    a = ap.parse_args()
    t0 = time.time()
    bands = ["K"] if a.quick else ["K", "H", "J"]
    rs = [2, 4]
    targets = ["usaf", "stars"]
    cells = [(t, b, r) for b in bands for r in rs for t in targets]
    for c in cells:
        os.makedirs(cell_dir(*c), exist_ok=True)
    model_keys = {row[0]: row[3] for row in ROWS if callable(row[3])}

    pool = cf.ThreadPoolExecutor(max_workers=2)
    # 1. Truths (closed loop) and wrong models (analytic); the unmodified scene's analytic PSFs too, to check that
    #    the user's route (simulate with analytic AO) gives the dataset's nominal_psfs.fits.
    jobs = [pool.submit(truth_job, *c, t) for c in cells for t in TRUTHS]
    mjobs = [pool.submit(model_job, *c, k, p) for c in cells for k, p in list(model_keys.items()) + [("nominal", None)]]
    truths = dict(f.result() for f in jobs)
    models = dict(f.result() for f in mjobs)
    nominal_check = max(compare_fits(os.path.join(truths[c + ("base",)]["dir"], "nominal_psfs.fits"),
                                     models[c + ("nominal",)]) for c in cells)
    t_sim = time.time() - t0

    # 2. Reconstructions. USAF: every method (MAP only at r = 2: ~13 s CPU per run at r = 4), drizzle once per
    #    truth (it uses no PSF). Stars: the linear method.
    def methods(target, r):
        if target == "stars":
            return ["linear"]
        return ["tikhonov", "linear", "tv"] + (["map"] if r == 2 and not a.quick else [])

    rjobs = []
    for c in cells:
        target, band, r = c
        for row in ROWS:
            if row[3] == "cli:stars" and target != "stars":
                continue
            margs = model_args(target, band, r, row, models, truths)
            for m in methods(target, r):
                rjobs.append(pool.submit(recon_job, target, band, r, row, m, margs, truths[c + (row[2],)]["dir"]))
        if target == "usaf":
            for t in TRUTHS:
                rjobs.append(pool.submit(recon_job, target, band, r, ("drizzle-" + t, "", t, "oracle"), "drizzle", [],
                                         truths[c + (t,)]["dir"]))
    res = dict(f.result() for f in rjobs)
    wall = time.time() - t0
    cpu = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu_s = cpu.ru_utime + cpu.ru_stime

    # ---- the report ----
    def oracle_of(row):
        return [o[0] for o in ROWS if o[2] == row[2] and o[3] == "oracle"][0]

    combos = [(b, r) for b in bands for r in rs]
    cmd = "/usr/bin/python3 bench/psf_knowledge.py%s" % (" --quick" if a.quick else "")
    L = ["<!-- produced by: %s -->" % cmd, "# How well the PSF must be known (issue 23 item 4)", "",
         "Command: `%s --out bench/results/psf_knowledge.md` (from the repository root, Release build), %s UTC, git %s. "
         "Wall time %.0f s (simulations %.0f s), CPU of the aosr processes %.0f s; 2 jobs of 1 thread; `uptime` at the "
         "end: `%s`." % (cmd, time.strftime("%Y-%m-%d %H:%M", time.gmtime()),
                          subprocess.run(["git", "-C", ROOT, "rev-parse", "--short", "HEAD"], capture_output=True,
                                         text=True).stdout.strip(), wall, t_sim, cpu_s,
                          subprocess.run(["uptime"], capture_output=True, text=True).stdout.strip()), "",
         "System: data/scenes/paper-sim-r2.json and -r4.json (paper-8m: 8 m, r0 = 15 cm at 550 nm, three layers, "
         "16x16 diffractive Shack-Hartmann at 640 nm with an R = 8 guide star, 17x17 DM, 800 Hz POL integrator "
         "g = 0.35, k = 1; closed-loop Monte-Carlo, 0.1 s per exposure; N = 4 raster; 128 px frames) with the science "
         "band set to K (2.2 um), H (1.65 um) or J (1.25 um) and the camera pixel at lambda/D in each band (the "
         "sampling in lambda/D is the paper's in every band; only the AO correction changes). USAF target, paper's "
         "noise (1 % of the brightest noiseless pixel). Star field: crowded-stars' 400 stars (K..J = 14..21 mag in "
         "the science band), its detector (photon, read and sky noise; sky 13.0 / 14.4 / 16.0 mag/arcsec^2 at K / H "
         "/ J) and its 64 lambda/D PSF window, seen through the same closed-loop system.", "",
         "Models: the wrong ones are NominalPsfs of the scene with one preset field changed, made as a user would: "
         "the modified scene simulated with `\"ao\": {\"mode\": \"analytic\"}` and its psfs.fits passed as "
         "`--model-psfs FILE` (check: this route reproduces the dataset's own nominal_psfs.fits to %.1e of the "
         "peak). NCPA: static_aberrations Noll 4-11, %s nm (50 nm RMS), in the truth only. DM gain: the truth's "
         "`ao.dm_gain` (the mirror applies 0.9 or 1.1 times the commanded stroke); the model is the unmodified "
         "scene's nominal. Guide star: the preset's Shack-Hartmann is noiseless, so the magnitude changes nothing "
         "until its noise is on; the gsR truths switch on photon noise and 1 e- read noise at R = R. Two models: the "
         "noiseless nominal one (the base scene's), and the noisy scene's own nominal model, whose analytic "
         "WFS-noise term is measured through the sensor and reconstructor (TelescopePreset::ToAnalyticAo; it "
         "leaves out the extra blur that the loop's residual adds to the spots, so at faint stars it is a lower "
         "bound). Differences (Delta) are against the oracle PSFs on the same data." % (
             nominal_check, ", ".join("%.1f" % t["rms_nm"] for t in ncpa_terms())), "",
         "Methods: `aosr reconstruct -m M` with defaults (Tikhonov: GCV; linear: target PSF auto; TV and MAP to "
         "their default stopping; MAP at r = 2 only); scores as reconstruct reports them (trustworthy border left "
         "out). Drizzle uses no PSF: one run per dataset, listed under each band.", ""]

    strehl = ["| band | r | long-exposure Strehl of the truth (mean over frames): %s | NCPA / base (Marechal: "
              "exp(-(2 pi 50 nm / lambda)^2)) | drizzle aligned PSNR base [dB] |" % " / ".join(TRUTHS),
              "|---|---:|---|---|---:|"]
    for b, r in combos:
        st = {t: truths[("usaf", b, r, t)]["strehl"] for t in TRUTHS}
        strehl.append("| %s | %d | %s | %.3f (%.3f) | %.2f |" % (
            b, r, " / ".join("%.3f" % st[t] for t in TRUTHS), st["ncpa"] / st["base"],
            math.exp(-(2 * math.pi * NCPA_RMS_NM * 1e-9 / BANDS[b]) ** 2),
            res[("usaf", b, r, "drizzle-base", "drizzle")]["psnr_al"]))
    L += strehl + [""]

    def header(first):
        return ["| %s | %s |" % (first, " | ".join("%s r=%d" % c for c in combos)),
                "|---|" + "---:|" * len(combos)]

    for m in ["tikhonov", "linear", "tv", "map"]:
        if m == "map" and a.quick:
            continue
        L += ["### %s, USAF: aligned PSNR against the oracle on the same data, Delta aligned (Delta raw) [dB]" % m, ""]
        L += header("model")
        for row in ROWS:
            cells_txt = []
            for b, r in combos:
                k = ("usaf", b, r, row[0], m)
                o = ("usaf", b, r, oracle_of(row), m)
                if k not in res:
                    cells_txt.append("")
                elif row[3] == "oracle":
                    cells_txt.append("%.2f" % res[k]["psnr_al"])
                else:
                    cells_txt.append("%+.2f (%+.2f)" % (res[k]["psnr_al"] - res[o]["psnr_al"],
                                                        res[k]["psnr"] - res[o]["psnr"]))
            if any(cells_txt):
                L.append("| %s | %s |" % (row[1], " | ".join(cells_txt)))
        L.append("")
    L.append("Oracle rows: the aligned PSNR itself [dB].")
    L.append("")

    L += ["### Linear output on the star field: photometric bias (median flux error of the %d brightest stars, "
          "aperture 1.5 camera px against the truth's) [%%], Delta against the oracle in brackets" % STARS_MEASURED, ""]
    L += header("model")
    for row in ROWS:
        txt = []
        for b, r in combos:
            k = ("stars", b, r, row[0], "linear")
            o = ("stars", b, r, oracle_of(row), "linear")
            if row[3] == "oracle":
                txt.append("%+.2f" % (100 * res[k]["bias"]))
            else:
                txt.append("%+.2f (%+.2f)" % (100 * res[k]["bias"], 100 * (res[k]["bias"] - res[o]["bias"])))
        L.append("| %s | %s |" % (row[1], " | ".join(txt)))
    L.append("")

    L += ["### Global offset of the Tikhonov output against the truth (dy, dx) [mas]", ""]
    L += header("model")
    for row in ROWS:
        txt = []
        if ("usaf", combos[0][0], combos[0][1], row[0], "tikhonov") not in res:
            continue
        for b, r in combos:
            k = res[("usaf", b, r, row[0], "tikhonov")]
            txt.append("%+.1f, %+.1f" % (k["dy_mas"], k["dx_mas"]))
        L.append("| %s | %s |" % (row[1], " | ".join(txt)))
    L.append("")

    L += ["### Every run (USAF)", "",
          "| band | r | model | method | PSNR aligned | SSIM aligned | offset dy, dx [HR px] | offset dy, dx [mas] | "
          "PSNR raw | Delta aligned | Delta raw | s |", "|---|---:|---|---|---:|---:|---|---|---:|---:|---:|---:|"]
    for b, r in combos:
        for row in ROWS + [("drizzle-" + t, "drizzle, truth " + t, t, "oracle") for t in TRUTHS]:
            for m in ["tikhonov", "linear", "tv", "map", "drizzle"]:
                k = ("usaf", b, r, row[0], m)
                if k not in res:
                    continue
                v = res[k]
                o = res.get(("usaf", b, r, oracle_of(row) if not row[0].startswith("drizzle") else row[0], m), v)
                L.append("| %s | %d | %s | %s | %.2f | %.4f | %+.3f, %+.3f | %+.2f, %+.2f | %.2f | %+.2f | %+.2f | %.1f |" % (
                    b, r, row[1], m, v["psnr_al"], v["ssim_al"], v["dy"], v["dx"], v["dy_mas"], v["dx_mas"], v["psnr"],
                    v["psnr_al"] - o["psnr_al"], v["psnr"] - o["psnr"], v["seconds"]))
    L.append("")
    json.dump({"results": {"/".join(map(str, k)): v for k, v in res.items()},
               "strehl": {"/".join(map(str, k)): v["strehl"] for k, v in truths.items()},
               "wall_seconds": wall, "cpu_seconds": cpu_s, "nominal_check": nominal_check},
              open(os.path.join(SCRATCH, "results.json"), "w"), indent=1)
    text = "\n".join(L)
    if a.out:
        old = open(a.out).read() if os.path.exists(a.out) else ""
        marker = "<!-- analysis -->"
        tail = old[old.index(marker):] if marker in old else marker + "\n## Analysis (by hand; kept by regeneration)\n\n(to be written)\n"
        open(a.out, "w").write(text + "\n" + tail)
    print(text)


if __name__ == "__main__":
    sys.exit(main())
