import os
from contextlib import AbstractContextManager
from typing import Any, Callable, Dict, Iterable, List, Optional, Sequence, TypeVar, Union

from . import Dataset, Reconstruction, Scene

T = TypeVar("T")
R = TypeVar("R")
ClientLike = Union[None, str, Any]  # None (LocalCluster), "serial", a scheduler address, a dask Client

RESULTS_FORMAT: str
RESULTS_VERSION: int

def get_client(client: ClientLike = None, n_workers: int = 2, threads_per_worker: int = 1,
               **cluster_kwargs: Any) -> AbstractContextManager[Any]: ...
def map_tasks(fn: Callable[[T], R], items: Iterable[T], client: ClientLike = None, progress: bool = False,
              n_workers: int = 2, key_prefix: Optional[str] = None) -> List[R]: ...
def reconstruct_many(datasets: Sequence[Union[str, "os.PathLike[str]", Dataset]], output_dir: Union[str, "os.PathLike[str]"],
                     method: str = "tikhonov", *, client: ClientLike = None, names: Optional[Sequence[str]] = None,
                     threads: int = 1, dtype: str = "float32", evaluate: bool = True, progress: bool = False,
                     n_workers: int = 2, results: Optional[str] = "results.json", **options: Any) -> List[Dict[str, Any]]: ...
def reconstruct_tiles(dataset: Union[str, "os.PathLike[str]"], output: Union[str, "os.PathLike[str]", None] = None,
                      method: str = "tikhonov", *, client: ClientLike = None, tile: int = 0, tile_overlap: int = -1,
                      memory_limit: Union[float, str, None] = None,
                      checkpoint_dir: Union[str, "os.PathLike[str]", None] = None, weights: str = "auto",
                      offsets: str = "auto", threads: int = 1, dtype: str = "float32", progress: bool = False,
                      n_workers: int = 2, **options: Any) -> Reconstruction: ...
def design_sweep(configs: Iterable[Dict[str, Any]], *, client: ClientLike = None, progress: bool = False,
                 n_workers: int = 2) -> List[Dict[str, Any]]: ...
def calibration_trials(spec: str = "paper-bench", seeds: Iterable[int] = ..., *, client: ClientLike = None,
                       progress: bool = False, n_workers: int = 2, synthesize: Optional[Dict[str, Any]] = None,
                       **calibrate_options: Any) -> List[Dict[str, Any]]: ...
