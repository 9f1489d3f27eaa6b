"""Simulated sequences (a scene's `sequence`, data/scenes/README.md): aosr.simulate gives M frames cycling through the
N phases with their times and the truth at each exposure, the same in memory as on disk, through pickling, and into
aosr.video, whose outputs follow the moving object. The shipped video scene loads and simulates."""
import pickle

import numpy as np
import pytest

import aosr

N, M, R, LR = 4, 10, 2, 32
DT = 0.05  # s between exposures; the frame time is 0.2 s / 4 = 0.05 s


def _scene(**sequence):
    return aosr.Scene({
        "name": "py-sequence", "seed": 5, "telescope": "paper-8m", "frames": N, "r": R,
        "offsets": {"type": "raster"},
        "sequence": {"frames": M, "frame_interval_s": DT, **sequence},
        "objects": [
            {"type": "stars", "catalogue": [{"y_px": 24.25, "x_px": 6.25, "flux_e": 4e4}],
             "variation": {"velocity_px_per_s": [0.0, 20.0]}},  # 1 camera px (2 HR px) per exposure
            {"type": "planet", "radius_px": 5, "centre_px": [8, 16], "rotation_period_s": 0.2,
             "flux": {"total_e": 1e5}},
        ],
        "detector": {"frame_px": LR, "total_exposure_s": 0.2, "noise": "none", "saturation": False},
    })


@pytest.fixture(scope="module")
def simulated(tmp_path_factory):
    out = tmp_path_factory.mktemp("sequence") / "sim"
    return aosr.simulate(_scene(), output=out), out


def test_frames_phases_times_and_truth_per_exposure(simulated):
    ds, _ = simulated
    assert len(ds.frames) == M and ds.phases == N
    assert ds.slots == [j % N for j in range(M)]
    np.testing.assert_allclose(ds.times_s, DT * np.arange(M) + 0.025, rtol=0, atol=1e-15)
    truth = np.asarray(ds.truth_frames)
    assert truth.shape == (M, R * LR, R * LR)
    np.testing.assert_allclose(ds.truth, truth.mean(axis=0), rtol=0, atol=1e-9 * truth.max())
    # The star moves 2 HR px per exposure along x: its deposit's centroid (rows 40..58, below the planet) follows.
    rows = slice(40, 58)
    cols = np.arange(R * LR)
    xs = [(t[rows] * cols).sum() / t[rows].sum() for t in truth]
    np.testing.assert_allclose(np.diff(xs), 2.0, rtol=0, atol=1e-9)
    # The planet turns once in 0.2 s = 4 exposures: exposure j + 4 shows the face of exposure j.
    top = truth[:, :30]
    np.testing.assert_allclose(top[4:], top[:-4], rtol=0, atol=1e-12 * top.max())
    assert np.abs(top[1] - top[0]).max() > 1e-3 * top.max()
    # The PSFs are per phase, repeated along the sequence.
    psfs = np.asarray(ds.psfs)
    np.testing.assert_array_equal(psfs[N:], psfs[:M - N])


def test_disk_memory_and_pickle_agree(simulated):
    ds, out = simulated
    disk = aosr.open_dataset(out)
    again = pickle.loads(pickle.dumps(ds))
    for other in (disk, again):
        assert other.slots == ds.slots and other.phases == ds.phases
        np.testing.assert_array_equal(other.times_s, ds.times_s)
        np.testing.assert_array_equal(other.truth_frames, ds.truth_frames)
        np.testing.assert_array_equal(other.frames, ds.frames)
        np.testing.assert_array_equal(other.psfs, ds.psfs)


def test_video_follows_the_moving_star(simulated):
    ds, _ = simulated
    outputs = list(aosr.video(ds, "tikhonov", "sliding", weights="mask", info=True))
    assert len(outputs) == M - N + 1
    truth = np.asarray(ds.truth_frames)
    rows = slice(40, 58)
    cols = np.arange(R * LR)
    for t, image, info in outputs:
        newest = max(info["frames"])
        assert t == pytest.approx(ds.times_s[newest])
        # The window's star is smeared over its N positions (2 HR px apart, frames newest - 3 .. newest): its
        # centroid is their mean, to a tenth of an HR px.
        img = np.clip(np.asarray(image)[rows], 0, None)
        x = (img * cols).sum() / img.sum()
        xs = [(truth[k][rows] * cols).sum() / truth[k][rows].sum() for k in info["frames"]]
        assert x == pytest.approx(np.mean(xs), abs=0.1)


def test_a_scene_without_sequence_has_no_times(tmp_path):
    s = aosr.Scene({
        "name": "still", "telescope": "paper-8m", "frames": 2, "r": 2, "offsets": {"type": "raster"},
        "objects": [{"type": "stars", "catalogue": [{"y_px": 8, "x_px": 8, "flux_e": 100}]}],
        "detector": {"frame_px": 16, "noise": "none"}})
    ds = aosr.simulate(s)
    assert ds.times_s is None and ds.truth_frames is None
    assert ds.slots == [0, 1] and ds.phases == 2


def test_variation_without_sequence_is_refused():
    with pytest.raises(aosr.InvalidArgument, match=r"variation.*\"sequence\" section"):
        aosr.Scene({
            "name": "bad", "telescope": "paper-8m", "frames": 2, "r": 2,
            "objects": [{"type": "stars", "catalogue": [{"y_px": 8, "x_px": 8, "flux_e": 100}],
                         "variation": {"velocity_px_per_s": [1, 0]}}],
            "detector": {"frame_px": 16}})


def test_the_shipped_video_scene_simulates():
    scene = aosr.load_scene(aosr.data_path("scenes", "video-planet.json"), {"sequence.frames": 8})
    ds = aosr.simulate(scene)
    assert len(ds.frames) == 8 and ds.phases == 4
    assert np.asarray(ds.truth_frames).shape == (8, 256, 256)
