"""aosr.distributed on a real `dask scheduler` with two `dask worker` processes on localhost: a batch of
datasets reconstructed identically to the serial loop, and a worker killed mid-run losing nothing."""
import contextlib
import importlib.util
import json
import os
import pathlib
import shutil
import signal
import subprocess
import sys
import time

import pytest

import aosr
import aosr.distributed as ad
from conftest import bits_equal

distributed = pytest.importorskip("distributed")

N_DATASETS = 6
OPTIONS = {"iterations": 40}  # tv: ~0.5 s per dataset, long enough to kill a worker mid-task


def _dask_command(name):
    """The modules behind `dask-scheduler` / `dask-worker` run by this interpreter (Debian's scripts run
    /usr/bin/python3, which would not see an aosr installed in a virtualenv), else the scripts."""
    if importlib.util.find_spec(f"distributed.cli.dask_{name}"):
        return [sys.executable, "-m", f"distributed.cli.dask_{name}"]
    return [shutil.which(f"dask-{name}") or f"dask-{name}"]


@pytest.fixture(scope="module")
def batch(tmp_path_factory, demo_scene_path):
    """Six small datasets (the demo scene at six seeds) written as the CLI would."""
    root = tmp_path_factory.mktemp("batch")
    scene = aosr.load_scene(demo_scene_path)
    paths = []
    for seed in range(N_DATASETS):
        out = root / f"night-{seed}"
        aosr.simulate(scene, seed=100 + seed, output=out)
        paths.append(str(out))
    return paths


@pytest.fixture(scope="module")
def serial(batch, tmp_path_factory):
    out = tmp_path_factory.mktemp("serial")
    records = ad.reconstruct_many(batch, out, "tv", client="serial", dtype="float64", **OPTIONS)
    return out, records


@contextlib.contextmanager
def _cluster(tmp_path):
    """A scheduler and two single-threaded workers, started by hand as a user would on several machines."""
    env = dict(os.environ, PYTHONDONTWRITEBYTECODE="1")
    scheduler_file = tmp_path / "scheduler.json"
    procs = [subprocess.Popen(_dask_command("scheduler") + ["--host", "127.0.0.1", "--port", "0",
                                                            "--no-dashboard", "--scheduler-file", str(scheduler_file)],
                              stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, env=env)]
    workers = []
    try:
        deadline = time.time() + 60
        while not scheduler_file.exists() and time.time() < deadline:
            time.sleep(0.1)
        assert scheduler_file.exists(), "the dask scheduler did not start"
        for i in range(2):
            w = subprocess.Popen(_dask_command("worker") + ["--scheduler-file", str(scheduler_file), "--nthreads", "1",
                                                            "--no-nanny", "--no-dashboard", "--name", f"w{i}"],
                                 stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, env=env)
            workers.append(w)
            procs.append(w)
        client = distributed.Client(scheduler_file=str(scheduler_file), timeout=60)
        client.wait_for_workers(2, timeout=60)
        yield client, workers
        client.close()
    finally:
        for p in procs:
            if p.poll() is None:
                p.terminate()
        for p in procs:
            try:
                p.wait(timeout=10)
            except subprocess.TimeoutExpired:
                p.kill()


@pytest.fixture(scope="module")
def cluster(tmp_path_factory):
    with _cluster(tmp_path_factory.mktemp("cluster")) as c:
        yield c


@pytest.fixture()
def fresh_cluster(tmp_path):
    """Its own cluster: the test kills one of its workers."""
    with _cluster(tmp_path) as c:
        yield c


def _same_outputs(a_dir, a_records, b_dir, b_records):
    assert len(a_records) == len(b_records) == N_DATASETS
    for a, b in zip(a_records, b_records):
        for k in ("name", "termination", "iterations", "regularisation", "image_sha256", "against_truth"):
            assert a[k] == b[k], k
        assert bits_equal(aosr.read_fits(a["output"])[0], aosr.read_fits(b["output"])[0])


def test_scheduler_and_two_workers_match_serial(batch, serial, cluster, tmp_path):
    client, _ = cluster
    out = tmp_path / "dist"
    records = ad.reconstruct_many(batch, out, "tv", client=client, dtype="float64", **OPTIONS)
    _same_outputs(serial[0], serial[1], out, records)
    assert len({r["worker_pid"] for r in records}) == 2   # both workers took part
    manifest = json.loads((out / "results.json").read_text())
    assert manifest["format"] == "aosr-batch-results" and [r["name"] for r in manifest["results"]] == \
        [os.path.basename(p) for p in batch]


def test_a_worker_killed_mid_run_loses_nothing(batch, serial, fresh_cluster, tmp_path):
    client, workers = fresh_cluster
    out = tmp_path / "killed"
    killer_done = []

    def kill_when_busy():
        # Wait until the second worker is executing a task, then SIGKILL it (no cleanup, no goodbye).
        victim = workers[1]
        deadline = time.time() + 60
        while time.time() < deadline:
            processing = client.processing()
            busy = [addr for addr, keys in processing.items() if keys]
            info = client.scheduler_info()["workers"]
            names = {addr: w.get("name") for addr, w in info.items()}
            if any(names.get(a) == "w1" for a in busy) and any(p.suffix == ".fits" for p in out.glob("*.fits")):
                victim.send_signal(signal.SIGKILL)
                killer_done.append(time.time())
                return
            time.sleep(0.05)

    import threading
    t = threading.Thread(target=kill_when_busy)
    t.start()
    records = ad.reconstruct_many(batch, out, "tv", client=client, dtype="float64", **OPTIONS)
    t.join()
    assert killer_done, "the worker was not killed mid-run"
    assert workers[1].wait(timeout=10) == -signal.SIGKILL
    _same_outputs(serial[0], serial[1], out, records)
    assert not list(out.glob("*.tmp-*"))                  # no temporary left, no partial file


def test_local_cluster_default(batch, serial, tmp_path, capsys):
    out = tmp_path / "local"
    records = ad.reconstruct_many(batch[:2], out, "tv", dtype="float64", n_workers=2, progress=True, **OPTIONS)
    assert "100%" in capsys.readouterr().out   # dask.distributed.progress's text bar
    _same_outputs_subset = [(a, b) for a, b in zip(serial[1][:2], records)]
    for a, b in _same_outputs_subset:
        assert a["image_sha256"] == b["image_sha256"]


def test_calibration_trials_on_workers_equal_serial(cluster, tmp_path):
    client, _ = cluster
    spec = tmp_path / "small.json"
    spec.write_text(json.dumps({"telescope": "paper-bench", "calibration": {
        "pixel_lambda_over_d": 0.3115, "window_px": [24, 24], "modes": [4], "gains": [0.9],
        "amplitudes_nm": [60], "references_per_mode": 1, "static_nm": {"4": 10}}}))
    kwargs = {"seeds": [1, 2], "static_max_noll": 0, "point_source": True}
    on_workers = ad.calibration_trials(str(spec), client=client, **kwargs)
    in_loop = ad.calibration_trials(str(spec), client="serial", **kwargs)
    assert [t["seed"] for t in on_workers] == [1, 2]
    assert [[m["gain"] for m in t["calibration"]["modes"]] for t in on_workers] == \
        [[m["gain"] for m in t["calibration"]["modes"]] for t in in_loop]
    assert [m["gain"] for m in on_workers[0]["truth"]["modes"]] == [0.9]


def test_design_sweep_on_workers_equals_serial(cluster):
    client, _ = cluster
    scene = aosr.load_scene(aosr.data_path("scenes", "paper-sim-r2.json"))
    configs = [{"scene": scene, "param": "tiptilt", "starts": 1, "iterations": 3, "realisations": 1, "seed": seed,
                "validation_realisations": 0} for seed in (1, 2)]
    on_workers = ad.design_sweep(configs, client=client)
    in_loop = ad.design_sweep(configs, client="serial")
    assert [r["design"]["design"] for r in on_workers] == [r["design"]["design"] for r in in_loop]
    assert [r["config"]["seed"] for r in on_workers] == [1, 2]


# ---- The tiles of one dataset on the workers ---------------------------------------------------------------

TILES = {"tile": 32, "tile_overlap": 12, "memory_limit": "4M"}  # the demo's 128² frames: 4 x 4 tiles
TILE_OPTIONS = {"iterations": 150}  # tv: ~0.1 s per tile, so that a worker is killed while it solves one


@pytest.fixture(scope="module")
def tiles_serial(batch):
    """The serial run by tiles without a whole-grid model (the memory limit forces it), in this process."""
    return aosr.reconstruct(batch[0], "tv", **TILES, **TILE_OPTIONS)


def test_tiles_on_two_workers_equal_the_serial_run(batch, tiles_serial, cluster, tmp_path):
    client, _ = cluster
    folder = tmp_path / "tiles"
    folder.mkdir()
    rec = ad.reconstruct_tiles(batch[0], tmp_path / "out.fits", "tv", client=client, checkpoint_dir=folder,
                               dtype="float64", **TILES, **TILE_OPTIONS)
    assert tiles_serial.memory_plan is not None and tiles_serial.memory_plan["tile"] == 32
    assert rec.regularisation == tiles_serial.regularisation
    assert "16 tiles resumed" in rec.summary["message"]
    assert rec.image.size == 0  # written by rows into the file, not held
    image, header = aosr.read_fits(tmp_path / "out.fits")
    assert bits_equal(image, tiles_serial.image)
    assert header["NTILES"] == 16 and header["TILEOVER"] == 12 and header["METHOD"] == "tv" and "CRVAL1" in header
    assert sorted(p.name for p in folder.iterdir()) == sorted(f"tile_{k}.bin" for k in range(16))
    # A rerun with the same folder solves nothing again: the blend alone, held in memory without an output.
    again = ad.reconstruct_tiles(batch[0], None, "tv", client="serial", checkpoint_dir=folder, **TILES, **TILE_OPTIONS)
    assert bits_equal(again.image, tiles_serial.image)


def test_tiles_survive_a_killed_worker(batch, tiles_serial, fresh_cluster, tmp_path):
    client, workers = fresh_cluster
    folder = tmp_path / "tiles"
    folder.mkdir()
    killed = []

    def kill_when_busy():
        victim = workers[1]
        deadline = time.time() + 60
        while time.time() < deadline:
            busy = [addr for addr, keys in client.processing().items() if keys]
            names = {a: w.get("name") for a, w in client.scheduler_info()["workers"].items()}
            # As soon as w1 holds a tile task (its first one also opens the dataset: the longest to run).
            if any(names.get(a) == "w1" for a in busy):
                victim.send_signal(signal.SIGKILL)
                killed.append(time.time())
                return
            time.sleep(0.05)

    import threading
    t = threading.Thread(target=kill_when_busy)
    t.start()
    rec = ad.reconstruct_tiles(batch[0], None, "tv", client=client, checkpoint_dir=folder, **TILES, **TILE_OPTIONS)
    t.join()
    assert killed, "the worker was not killed mid-run"
    assert workers[1].wait(timeout=10) == -signal.SIGKILL
    assert bits_equal(rec.image, tiles_serial.image)
    assert not [p for p in folder.iterdir() if not p.name.endswith(".bin")]  # no temporary left


@pytest.fixture(scope="module")
def field_path(tmp_path_factory):
    """A dataset whose PSF varies over the field (a 2 x 2 grid of field points: tiles of 32 camera px)."""
    from test_psf_field import field_scene
    out = tmp_path_factory.mktemp("field") / "field"
    aosr.simulate(aosr.Scene(field_scene(frame_px=64)), output=out)
    return str(out)


@pytest.mark.parametrize("method", ["tikhonov", "linear"])
def test_tiles_of_a_field_varying_psf_on_two_workers_equal_the_serial_run(field_path, cluster, tmp_path, method):
    # Each task interpolates its tile's local PSFs from the dataset's PSF grid, as aosr.reconstruct does.
    serial = aosr.reconstruct(field_path, method, psf_field="tiles")
    client, _ = cluster
    rec = ad.reconstruct_tiles(field_path, tmp_path / "out.fits", method, client=client, dtype="float64")
    image, header = aosr.read_fits(tmp_path / "out.fits")
    assert serial.psf_field == "tiles" and rec.psf_field == "tiles"
    assert rec.regularisation == serial.regularisation
    assert "4 tiles resumed" in rec.summary["message"]
    assert bits_equal(image, serial.image)
    assert header["PSFFIELD"].startswith("tiles 2x2")
    # The guide star's PSF everywhere is another image; the space-variant operator is not tiles.
    none = ad.reconstruct_tiles(field_path, None, method, client="serial", psf_field="none", tile=32)
    assert none.psf_field == "none" and not bits_equal(none.image, serial.image)
    with pytest.raises(aosr.InvalidArgument, match="psf_field"):
        ad.reconstruct_tiles(field_path, None, method, client="serial", psf_field="operator")


def test_a_failed_tile_task_raises_and_writes_nothing(batch, cluster, tmp_path):
    # The blend runs beside the tasks: a task's error (here a file in the folder that is not a tile) reaches the
    # caller, the other tasks are cancelled and no output appears.
    client, _ = cluster
    folder = tmp_path / "tiles"
    folder.mkdir()
    (folder / "tile_5.bin").write_bytes(b"not a tile")
    out = tmp_path / "out.fits"
    with pytest.raises(aosr.InvalidArgument, match="tile_5.bin"):
        ad.reconstruct_tiles(batch[0], out, "tikhonov", client=client, checkpoint_dir=folder, **TILES)
    assert not [p for p in tmp_path.iterdir() if p.name.startswith("out")]


def test_reconstruct_tiles_never_overwrites_an_input(batch):
    folder = batch[0]
    manifest = json.loads((pathlib.Path(folder) / "manifest.json").read_text())
    frames = pathlib.Path(folder) / manifest["frames"]
    before = frames.read_bytes()
    with pytest.raises(aosr.InvalidArgument, match="output"):
        ad.reconstruct_tiles(folder, frames, "tikhonov", client="serial", **TILES)
    assert frames.read_bytes() == before


@pytest.mark.parametrize("kwargs,needle", [
    ({"dtype": "int8"}, "dtype"),
    ({"checkpoint_dir": "/nonexistent/aosr"}, "checkpoint_dir"),
    ({"tile": -3}, "tile"),
    ({"memory_limit": "300K"}, "memory"),
    ({"psf_field": "bogus"}, "psf_field"),
])
def test_reconstruct_tiles_bad_arguments(batch, kwargs, needle):
    with pytest.raises((aosr.InvalidArgument, aosr.ResourceError), match=needle):
        ad.reconstruct_tiles(batch[0], None, "tikhonov", client="serial", **kwargs)


def test_local_cluster_workers_start_with_the_allocator_tunables():
    # glibc reads GLIBC_TUNABLES when a process starts: the variable must be in the workers' starting environment
    # (/proc/self/environ), not only put into os.environ once the worker runs (Dask 2022.12's LocalCluster(env=)).
    if not os.path.exists("/proc/self/environ"):
        pytest.skip("no /proc")
    expected = ad._allocator_environment().get("GLIBC_TUNABLES")
    if expected is None:
        pytest.skip("the environment chose its own malloc settings")

    def starting_environment():
        with open("/proc/self/environ", "rb") as f:
            pairs = [item.split(b"=", 1) for item in f.read().split(b"\0") if b"=" in item]
        return {k.decode(): v.decode() for k, v in pairs}

    before = os.environ.get("GLIBC_TUNABLES")
    with ad.get_client(None, n_workers=1) as client:
        environments = list(client.run(starting_environment).values())
    # glibc parses the variable in place at start-up, cutting /proc's copy at its first ':'.
    assert environments and all(e.get("GLIBC_TUNABLES") and expected.startswith(e["GLIBC_TUNABLES"])
                                for e in environments), [e.get("GLIBC_TUNABLES") for e in environments]
    assert "glibc.malloc.hugetlb=1" in expected
    assert os.environ.get("GLIBC_TUNABLES") == before   # the client's own environment is as it was
