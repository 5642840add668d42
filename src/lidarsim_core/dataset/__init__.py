"""Datasets of many frames: generation, manifest, resume, splits and Dask execution.

The entry point is :func:`generate_dataset` (the ``lidarsim dataset`` command). Dask is
imported only when ``workers`` or ``scheduler`` is given (extra ``dask``).
"""

from .config import DatasetConfig, SequenceSpec, load_plan
from .frames import FrameJob, run_frame_job, worker_cache_info
from .generate import DatasetResult, generate_dataset
from .manifest import read_manifest
from .reader import TrainingSet, open_dataset

__all__ = ["DatasetConfig", "DatasetResult", "FrameJob", "SequenceSpec", "generate_dataset",
           "load_plan", "open_dataset", "read_manifest", "run_frame_job", "TrainingSet",
           "worker_cache_info"]
