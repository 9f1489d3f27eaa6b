"""aosr.distributed: the embarrassingly parallel work of aosr mapped over a ``dask.distributed.Client``.

Each function maps one library call per item (a dataset to reconstruct, a tile of one dataset, a design
configuration, a calibration trial) over a Dask client and gathers the results in input order. There is no algorithm and no scheduler
here: Dask schedules, retries and reports progress; aosr computes.

Which client (the ``client`` argument of every function):

* ``None`` (default): a ``LocalCluster`` of ``n_workers`` processes with one thread each, closed at the end,
  whose workers start with aosr's malloc settings and transparent huge pages (``_allocator_environment``; for
  a cluster of your own, start ``dask worker`` with the same ``GLIBC_TUNABLES``);
* a scheduler address such as ``"tcp://10.0.0.5:8786"``: the same code on every machine whose
  ``dask worker`` joined that scheduler (each needs ``import aosr`` to work, and the dataset paths to be
  visible, e.g. on a shared filesystem);
* a ``dask.distributed.Client`` you made (left open);
* ``"serial"``: no Dask at all, the same task function in a plain loop in this process (the reference the
  distributed results are identical to, bit for bit: each task is deterministic and uses ``threads``
  aosr threads, and aosr's results do not depend on the thread count).

Robustness: a worker that dies mid-task (killed, out of memory, machine lost) loses its tasks; the scheduler
gives them to another worker (up to Dask's ``distributed.scheduler.allowed-failures``, 3 by default).
Outputs are written atomically (aosr's FITS writer writes a temporary ``<name>.tmp-<pid>-<n>`` in the same
folder and renames it; the results manifest is written the same way with ``os.replace``), so a file under
its final name is always complete; temporaries a killed worker left behind are removed at the end of the
batch. Progress: ``dask.distributed.progress`` (a text bar in a terminal, a widget in a notebook).
"""

import contextlib
import glob
import hashlib
import json
import os
import shutil
import tempfile

import aosr

__all__ = ["get_client", "reconstruct_many", "reconstruct_tiles", "design_sweep", "calibration_trials", "map_tasks"]

RESULTS_FORMAT = "aosr-batch-results"
RESULTS_VERSION = 1


@contextlib.contextmanager
def get_client(client=None, n_workers=2, threads_per_worker=1, **cluster_kwargs):
    """A context manager yielding a ``dask.distributed.Client`` (or ``None`` for ``"serial"``).

    ``client``: None (a new LocalCluster of ``n_workers`` processes x ``threads_per_worker`` threads, closed on
    exit), a scheduler address string, an existing Client (not closed on exit) or ``"serial"``.
    ``cluster_kwargs`` go to ``LocalCluster``.
    """
    if client == "serial":
        yield None
        return
    try:
        from dask.distributed import Client, LocalCluster
    except ImportError as e:
        raise ImportError("aosr.distributed needs Dask's distributed scheduler: on Debian 12, apt-get install "
                          "python3-distributed (scripts/setup.sh --tests installs it)") from e

    if client is None:
        cluster_kwargs.setdefault("dashboard_address", None)
        cluster_kwargs.setdefault("processes", True)
        env = _allocator_environment() if cluster_kwargs["processes"] and "env" not in cluster_kwargs else {}
        with _pre_spawn_environment(env):
            cluster = LocalCluster(n_workers=n_workers, threads_per_worker=threads_per_worker, **cluster_kwargs)
        with cluster:
            with Client(cluster) as c:
                yield c
        return
    if isinstance(client, str):
        with Client(client) as c:
            yield c
        return
    yield client


@contextlib.contextmanager
def _pre_spawn_environment(env):
    """Gives new worker processes ``env`` in their starting environment. glibc reads GLIBC_TUNABLES once, when a
    process starts, and Dask 2022.12's ``LocalCluster(env=...)`` sets its variables inside the worker after that
    (nanny.py: ``os.environ.update(env)`` in the new process), so the workers never had the huge pages this asks
    for. Only ``distributed.nanny.pre-spawn-environ`` is set before the spawn; each nanny keeps the value it read
    at its start, for the workers it restarts too. (The nanny writes those variables into the client's own
    ``os.environ``; this puts them back once the workers have started.)"""
    if not env:
        yield
        return
    import dask

    key = "distributed.nanny.pre-spawn-environ"
    # A variable the client already has would win over the config's value (nanny.py, _get_env_variables): ours
    # (which extends the client's own GLIBC_TUNABLES, _allocator_environment) is set for the spawn, then undone.
    # The nanny also writes the variables into this process's os.environ as it spawns; they are put back as they
    # were once the workers have started (a worker restarted later sets them again).
    saved = {k: os.environ.get(k) for k in env}
    try:
        os.environ.update({k: v for k, v in env.items() if saved[k] is not None})
        with dask.config.set({key: dict(dask.config.get(key, default={}) or {}, **env)}):
            yield
    finally:
        for k, v in saved.items():
            if v is None:
                os.environ.pop(k, None)
            else:
                os.environ[k] = v


def _allocator_environment():
    """The environment a new worker process starts with for glibc's malloc (what the ``aosr`` launcher gives its
    engine, src/cli/launcher/launcher.cpp): the thresholds aosr.tune_allocator sets, and transparent huge pages for
    malloc's memory, which only a process's starting environment can ask for. Empty when the user chose malloc
    settings (GLIBC_TUNABLES with glibc.malloc.*, MALLOC_*_ variables) or set AOSR_MALLOC_TUNING=0."""
    if os.environ.get("AOSR_MALLOC_TUNING") == "0":
        return {}
    if any(name in os.environ for name in ("MALLOC_MMAP_THRESHOLD_", "MALLOC_TRIM_THRESHOLD_", "MALLOC_TOP_PAD_")):
        return {}
    tunables = os.environ.get("GLIBC_TUNABLES", "")
    if "glibc.malloc." in tunables:
        return {}
    ours = ("glibc.malloc.hugetlb=1:glibc.malloc.mmap_threshold=33554432:glibc.malloc.trim_threshold=1073741824:"
            "glibc.malloc.mmap_max=0")
    return {"GLIBC_TUNABLES": f"{tunables}:{ours}" if tunables else ours}


def map_tasks(fn, items, client=None, progress=False, n_workers=2, key_prefix=None):
    """``[fn(item) for item in items]``, one Dask task per item on ``client`` (see the module doc), results in
    input order. ``fn`` must be importable by the workers (a module-level function). An exception in a task is
    raised here (after the other tasks finished or failed)."""
    items = list(items)
    if client == "serial":
        return [fn(item) for item in items]
    with get_client(client, n_workers=n_workers) as c:
        # pure=False: every item is its own task even if two items are equal (each writes its own output).
        kwargs = {"pure": False}
        if key_prefix:
            kwargs["key"] = [f"{key_prefix}-{i}" for i in range(len(items))]
        futures = c.map(fn, items, **kwargs)
        if progress:
            from dask.distributed import progress as dask_progress

            dask_progress(futures)
        return c.gather(futures)


# ---- Reconstruction of many datasets -----------------------------------------------------------------------

def _write_json_atomically(path, data):
    folder = os.path.dirname(os.path.abspath(path))
    fd, tmp = tempfile.mkstemp(prefix=os.path.basename(path) + ".tmp-", dir=folder)
    try:
        with os.fdopen(fd, "w") as f:
            json.dump(data, f, indent=2, sort_keys=False)
            f.write("\n")
            f.flush()
            os.fsync(f.fileno())
        os.replace(tmp, path)
    except BaseException:
        with contextlib.suppress(OSError):
            os.remove(tmp)
        raise


def _dataset_name(dataset, index):
    if isinstance(dataset, (str, os.PathLike)):
        path = os.path.abspath(os.fspath(dataset))
        if os.path.basename(path) == "manifest.json":
            path = os.path.dirname(path)
        return os.path.basename(path.rstrip(os.sep)) or f"dataset-{index:04d}"
    return f"dataset-{index:04d}"


def _prepare_worker(threads):
    """Per task: aosr's thread count, and glibc's malloc thresholds as aosr's import sets them. Dask's nanny starts
    workers with MALLOC_TRIM_THRESHOLD_=65536 (``distributed.nanny.pre-spawn-environ``), under which every image a
    solver frees is handed back to the kernel and faulted in again on its next use: 16 TV reconstructions at 512²
    on 2 workers ran 1.43x the serial loop with it and ~1.8x without (bench/results/python.md).
    AOSR_MALLOC_TUNING=0 keeps Dask's setting."""
    aosr.set_threads(threads)
    aosr.tune_allocator(override_environment=True)


def _reconstruct_task(task):
    """One dataset: reconstruct, write ``<output>.fits`` (and the aux map) atomically, return its record."""
    _prepare_worker(task["threads"])
    dataset = task["dataset"]
    ds = dataset if isinstance(dataset, aosr.Dataset) else aosr.open_dataset(dataset)
    rec = aosr.reconstruct(ds, task["method"], **task["options"])
    # The keywords `aosr reconstruct` writes (with the HR grid's WCS and BUNIT from the dataset).
    header = {
        "ORIGIN": f"aosr {aosr.__version__}",
        "AOSRDATA": "reconstruction",
        "METHOD": task["method"],
        "SRFACTOR": ds.r,
        "NFRAMES": len(ds),
        "REGUL": rec.regularisation,
        "TERMINAT": rec.summary["termination"],
        "NITER": rec.summary["iterations"],
    }
    header.update(ds.hr_header("electron"))
    output = task["output"]
    aosr.write_fits(output, rec.image, header, dtype=task["dtype"])
    record = {
        "name": task["name"],
        "dataset": os.fspath(dataset) if isinstance(dataset, (str, os.PathLike)) else task["name"],
        "output": output,
        "method": task["method"],
        "termination": rec.summary["termination"],
        "message": rec.summary["message"],
        "iterations": rec.summary["iterations"],
        "regularisation": rec.regularisation,
        "seconds": rec.seconds_total,
        "image_sha256": hashlib.sha256(rec.image.tobytes()).hexdigest(),
        "worker_pid": os.getpid(),
    }
    if rec.aux is not None:
        stem, ext = os.path.splitext(output)
        aux = f"{stem}_{'weight' if rec.aux_name == 'weight' else 'std'}{ext}"
        aux_header = dict(header, AOSRDATA=rec.aux_name)
        aux_header.update(ds.hr_header("" if rec.aux_name == "weight" else "electron"))
        aosr.write_fits(aux, rec.aux, aux_header, dtype=task["dtype"])
        record["aux"] = {"name": rec.aux_name, "path": aux}
    if task["evaluate"]:
        if ds.truth is not None:
            m = aosr.evaluate(rec.image, dataset=ds)
            record["against_truth"] = {k: m[k] for k in ("psnr_db", "ssim", "rmse", "crop_px", "aligned",
                                                         "offset_hr_px", "offset_mas")}
    return record


def _remove_stale_temporaries(outputs):
    """Temporaries ``<output>.tmp-*`` left by workers killed while writing (never a final name)."""
    for output in outputs:
        for tmp in glob.glob(glob.escape(output) + ".tmp-*"):
            with contextlib.suppress(OSError):
                os.remove(tmp)


def reconstruct_many(datasets, output_dir, method="tikhonov", *, client=None, names=None, threads=1,
                     dtype="float32", evaluate=True, progress=False, n_workers=2, results="results.json",
                     **options):
    """Reconstructs every dataset with one method, one Dask task per dataset, and writes one FITS per dataset
    plus a results manifest.

    datasets    dataset folders / manifest paths (visible to every worker) or aosr.Dataset objects (shipped
                to the workers by pickling)
    output_dir  created if needed; gets ``<name>.fits`` (and ``<name>_weight.fits`` / ``<name>_std.fits``)
                per dataset and ``results`` (a JSON manifest: format, method, options, one record per
                dataset in input order)
    method, **options   as aosr.reconstruct (the CLI's defaults)
    names       output names (default: the dataset folders' names, or dataset-0000, ...)
    threads     aosr threads per task (1: the cluster's workers x threads provide the parallelism)
    dtype       'float32' (as the CLI writes) or 'float64' (exact)
    evaluate    add PSNR/SSIM/RMSE against the truth when a dataset has one (as `aosr reconstruct` prints)
    client, n_workers, progress   see the module doc

    Returns the list of records (what the manifest's "results" holds). Identical for any client.
    """
    datasets = list(datasets)
    if names is None:
        names = [_dataset_name(d, i) for i, d in enumerate(datasets)]
    names = list(names)
    if len(names) != len(datasets) or len(set(names)) != len(names):
        raise aosr.InvalidArgument(
            f"aosr.distributed.reconstruct_many: invalid names ({len(set(names))} distinct for {len(datasets)} "
            "datasets); allowed: one distinct name per dataset")
    if dtype not in ("float32", "float64"):
        raise aosr.InvalidArgument(f"aosr.distributed.reconstruct_many: invalid dtype = {dtype}; allowed: float32 | float64")
    if method not in aosr.methods():
        raise aosr.InvalidArgument(f"aosr.distributed.reconstruct_many: invalid method = {method}; allowed: "
                                   + " | ".join(aosr.methods()))
    os.makedirs(output_dir, exist_ok=True)
    output_dir = os.path.abspath(output_dir)
    tasks = [{
        "dataset": os.path.abspath(os.fspath(d)) if isinstance(d, (str, os.PathLike)) else d,
        "name": name,
        "output": os.path.join(output_dir, name + ".fits"),
        "method": method,
        "options": options,
        "threads": threads,
        "dtype": dtype,
        "evaluate": evaluate,
    } for d, name in zip(datasets, names)]
    try:
        records = map_tasks(_reconstruct_task, tasks, client=client, progress=progress, n_workers=n_workers)
    finally:
        _remove_stale_temporaries([t["output"] for t in tasks])
    manifest = {
        "format": RESULTS_FORMAT,
        "version": RESULTS_VERSION,
        "software": f"aosr {aosr.__version__}",
        "method": method,
        "options": {k: v for k, v in options.items() if isinstance(v, (str, int, float, bool, type(None)))},
        "results": records,
    }
    if results:
        _write_json_atomically(os.path.join(output_dir, results), manifest)
    return records


# ---- The tiles of one dataset ------------------------------------------------------------------------------

def _tile_task(task):
    """One tile of a plan, solved into the shared checkpoint folder (atomically: a worker killed mid-write
    leaves no tile). Returns the tile's record."""
    _prepare_worker(task["threads"])
    record = aosr._aosr._tiles(task["dataset"], task["method"], phase="solve", plan=task["plan"],
                               tiles=[task["tile"]], checkpoint_dir=task["checkpoint_dir"], weights=task["weights"],
                               offsets=task["offsets"], options=task["options"], psf_field=task["psf_field"],
                               keep=True)
    record["tile"] = task["tile"]
    record["worker_pid"] = os.getpid()
    return record


def reconstruct_tiles(dataset, output=None, method="tikhonov", *, client=None, tile=0, tile_overlap=-1,
                      memory_limit=None, checkpoint_dir=None, weights="auto", offsets="auto", threads=1,
                      dtype="float32", progress=False, n_workers=2, psf_field="auto", **options):
    """Reconstructs one dataset by tiles, one Dask task per tile: a detector too large for one process's memory,
    or one reconstruction spread over a cluster (solvers/tiling.hpp, "A whole detector").

    The client plans once: the dataset's tiles (``tile`` camera px, or the largest whose run fits
    ``memory_limit``), their overlap, one regularisation for the whole field (λ, κ or TV's μ, chosen on a
    central window) and the weights' rule (the pooled background variance, whether any pixel is masked), read from
    the frames in bands of rows. Each
    task opens the dataset from its path (shared storage: frames are not shipped through the scheduler), reads
    only its tile's window of the frames, masks and weights (cfitsio reads the section), solves the tile with the
    plan's options and writes it to ``checkpoint_dir``. The client blends the tiles in order as their tasks
    finish, beside the tasks still running, written by rows into ``output`` (the image is never held whole). The image has the bytes of the serial run
    ``aosr.reconstruct(dataset, method, tile=..., tile_overlap=..., memory_limit=...)`` by tiles without a
    whole-grid model, whoever solved which tile; a task whose worker dies is run again by Dask, and a rerun with
    the same ``checkpoint_dir`` solves only the tiles that are missing.

    dataset         a dataset folder or manifest path every worker can read
    output          optional FITS path: the image (``dtype``) with the HR grid's WCS and the run's keywords (as
                    `aosr reconstruct` writes them), written by rows and renamed into place at the end; the second
                    map (Tikhonov's σ, ...) beside it as <stem>_std.fits. The returned Reconstruction then holds
                    no image (read the file: aosr.read_fits, or astropy with memmap)
    method, **options   as aosr.reconstruct (the CLI's defaults)
    tile, tile_overlap, memory_limit   as aosr.reconstruct; tile 0 chooses the tiles under memory_limit
    checkpoint_dir  an existing folder on shared storage for the tiles (kept: a rerun resumes from it); None: a
                    temporary folder next to ``output`` (or in the system's temporary folder), removed at the end
    threads         aosr threads per task
    psf_field       as aosr.reconstruct: 'auto' (a dataset with a field-varying PSF is reconstructed by tiles with
                    its local PSFs, the tiles then half the PSF grid's spacing unless ``tile`` is given) | 'none'
                    (the dataset's own PSFs everywhere) | 'tiles'. The space-variant 'operator' is one solve over
                    the whole field, not tiles: aosr.reconstruct
    client, n_workers, progress   see the module doc

    Returns the aosr.Reconstruction of the blend (its summary says how many tiles and that they were resumed
    from the folder); its image is empty (0 x 0) when ``output`` is given.
    """
    if not isinstance(dataset, (str, os.PathLike)):
        raise aosr.InvalidArgument("aosr.distributed.reconstruct_tiles: invalid dataset = "
                                   f"{type(dataset).__name__}; allowed: a dataset folder or manifest path that "
                                   "every worker can read")
    if dtype not in ("float32", "float64"):
        raise aosr.InvalidArgument(f"aosr.distributed.reconstruct_tiles: invalid dtype = {dtype}; allowed: "
                                   "float32 | float64")
    if checkpoint_dir is not None and not os.path.isdir(checkpoint_dir):
        raise aosr.InvalidArgument(f"aosr.distributed.reconstruct_tiles: invalid checkpoint_dir = {checkpoint_dir}; "
                                   "allowed: an existing folder (on storage the workers share)")
    dataset = os.path.abspath(os.fspath(dataset))
    if output:
        inputs = set(aosr._aosr._dataset_input_files(dataset))  # the CLI's rule (scene/dataset.hpp)
        stem, ext = os.path.splitext(os.path.abspath(os.fspath(output)))
        for path in (os.fspath(output), stem + "_std" + ext, stem + "_weight" + ext):
            if os.path.realpath(path) in inputs:
                raise aosr.InvalidArgument(f"aosr.distributed.reconstruct_tiles: invalid output = {output}; allowed: "
                                           f"a path that is not one of the dataset's input files ({path})")
    common = {"weights": weights, "offsets": offsets, "options": options, "psf_field": psf_field}
    # The client keeps the dataset's FieldData from the plan to the blend (and for tasks run here with
    # client="serial"), and frees it at the end.
    plan = aosr._aosr._tiles(dataset, method, phase="plan", tile=tile, tile_overlap=tile_overlap,
                             memory_limit=memory_limit, keep=True, **common)
    own_folder = checkpoint_dir is None
    if own_folder:
        parent = os.path.dirname(os.path.abspath(output)) if output else None
        checkpoint_dir = tempfile.mkdtemp(prefix="aosr-tiles-", dir=parent)
    checkpoint_dir = os.path.abspath(checkpoint_dir)
    try:
        tasks = [dict(common, dataset=dataset, method=method, plan=plan, tile=k, checkpoint_dir=checkpoint_dir,
                      threads=threads) for k in range(plan["tiles"])]
        key = hashlib.sha256(json.dumps([dataset, method, plan, weights, offsets, psf_field,
                                         repr(sorted(options.items())), checkpoint_dir],
                                        sort_keys=True, default=str).encode()).hexdigest()[:16]
        blend = dict(common, plan=plan, checkpoint_dir=checkpoint_dir, keep=True,
                     output=os.fspath(output) if output else "", dtype=dtype)
        if client == "serial":
            map_tasks(_tile_task, tasks, client="serial")
            rec = aosr._aosr._tiles(dataset, method, phase="blend", **blend)
        else:
            with get_client(client, n_workers=n_workers) as c:
                futures = c.map(_tile_task, tasks, pure=False, key=[f"aosr-tile-{key}-{k}" for k in range(len(tasks))])
                try:
                    if progress:
                        from dask.distributed import progress as dask_progress

                        dask_progress(futures)
                    # The blend takes the tiles in order as their tasks finish, beside the tasks still running
                    # (its bytes do not depend on when a tile came): only the last tiles' share of it is left
                    # once the last task ends. A failed task raises here, as map_tasks would.
                    rec = aosr._aosr._tiles(dataset, method, phase="blend",
                                            await_tiles=lambda first, last: [f.result() for f in futures[first:last]],
                                            **blend)
                except BaseException:
                    c.cancel(futures)
                    raise
    finally:
        aosr._aosr._tiles_forget()
        _remove_stale_temporaries([os.path.join(checkpoint_dir, f"tile_{k}.bin") for k in range(plan["tiles"])])
        if own_folder:
            shutil.rmtree(checkpoint_dir, ignore_errors=True)
    return rec


# ---- Design sweeps -----------------------------------------------------------------------------------------

def _design_task(config):
    config = dict(config)
    config.setdefault("threads", 1)
    _prepare_worker(1)
    scene = config.pop("scene")
    return {"config": {"scene": os.fspath(scene) if isinstance(scene, (str, os.PathLike)) else scene.source,
                       **{k: v for k, v in config.items() if k != "output"}},
            "design": aosr.design(scene, **config)}


def design_sweep(configs, *, client=None, progress=False, n_workers=2):
    """Runs aosr.design once per configuration, one Dask task each.

    configs: dicts of aosr.design's arguments with a "scene" (a scene path or aosr.Scene), e.g. a grid over
    parameterisations and seeds: ``[{"scene": s, "param": p, "seed": k, "threads": 1} for p in ... for k in ...]``
    (threads: the design's own threads per task, default 1: the cluster provides the parallelism). A config's
    "output" writes its design file (atomically, by the library). Returns ``[{"config", "design"}]`` in
    input order, "design" being what aosr.design returns.
    """
    if not hasattr(aosr, "design"):
        raise NotImplementedError("aosr.design is not available in this build")
    return map_tasks(_design_task, list(configs), client=client, progress=progress, n_workers=n_workers)


# ---- Calibration Monte-Carlo -------------------------------------------------------------------------------

def _calibration_task(task):
    _prepare_worker(1)
    s = aosr.synthesize_calibration(task["spec"], seed=task["seed"], **task["synthesize"])
    result = aosr.calibrate(s, **task["calibrate"])
    return {"seed": task["seed"], "truth": s.truth, "calibration": result}


def calibration_trials(spec="paper-bench", seeds=range(10), *, client=None, progress=False, n_workers=2,
                       synthesize=None, **calibrate_options):
    """Monte-Carlo of the modal-gain calibration: for each seed, a synthetic set (aosr.synthesize_calibration
    with that seed and ``synthesize`` options) is made and calibrated (aosr.calibrate with
    ``calibrate_options``; threads defaults to 1 per task), one Dask task per seed, in memory.

    Returns ``[{"seed", "truth", "calibration"}]`` in seed order: the injected truth and the calibration
    dict, from which coverage (|gain - true| <= 2 sigma) and scatter follow.
    """
    calibrate_options.setdefault("threads", 1)
    tasks = [{"spec": spec, "seed": int(s), "synthesize": dict(synthesize or {}), "calibrate": calibrate_options}
             for s in seeds]
    return map_tasks(_calibration_task, tasks, client=client, progress=progress, n_workers=n_workers)
