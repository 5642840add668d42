"""Point sources that exporters read in chunks, so no exporter needs a whole frame in memory.

An exporter's :meth:`~lidarsim_core.io.base.Exporter.write_points` receives a
:class:`PointSource`: the number of points and the frame metadata are known up front (file
headers need them), and the columns are read back in chunks of any size, as many times as the
exporter wants (NumPy archives are written one column at a time, the others row chunk by row
chunk). Two implementations:

* :class:`CloudPoints` wraps an in-memory :class:`~lidarsim_core.records.pointcloud.PointCloud`;
* :class:`PointSpool` collects the chunks of a running simulation, in memory up to a byte budget
  and in an anonymous temporary file beyond it, so memory stays bounded whatever the number of
  points in the frame. Chunks come back re-cut to the size the exporter asks for, so the bytes
  written never depend on how the simulation chunked its rays.
"""

from __future__ import annotations

import json
import tempfile
from abc import ABC, abstractmethod
from typing import IO, Iterable, Iterator, Sequence

import numpy as np

from ..records.pointcloud import POINT_FIELDS, FrameInfo, PointCloud

#: Points per chunk handed to exporters unless they ask for another size.
DEFAULT_CHUNK_POINTS = 65536
#: Bytes of point records a :class:`PointSpool` keeps in memory before it spills to disk.
DEFAULT_SPOOL_MEMORY = 64 * 2 ** 20


def column_dtypes(columns: dict[str, np.ndarray]) -> dict[str, np.dtype]:
    """Column name → dtype: the point-record fields in :data:`POINT_FIELDS` order and dtype,
    then any further columns (e.g. added by a plugin) in their given order and dtype."""
    out = {name: np.dtype(dtype) for name, dtype in POINT_FIELDS.items() if name in columns}
    out.update({name: np.asarray(values).dtype for name, values in columns.items()
                if name not in out})
    return out


def frame_metadata_json(frame: FrameInfo) -> str:
    """The frame metadata as one line of compact, key-sorted JSON (as
    :meth:`PointCloud.metadata_json`)."""
    return json.dumps(frame.to_dict(), sort_keys=True, separators=(",", ":"))


class PointSource(ABC):
    """Points of one frame, readable in chunks.

    Attributes
    ----------
    frame
        The frame metadata.
    """

    frame: FrameInfo

    @abstractmethod
    def __len__(self) -> int:
        """Number of points."""

    @property
    @abstractmethod
    def fields(self) -> dict[str, np.dtype]:
        """Column name → dtype, point-record fields first (see :func:`column_dtypes`)."""

    @abstractmethod
    def iter_chunks(self, columns: Sequence[str] | None = None,
                    size: int = DEFAULT_CHUNK_POINTS) -> Iterator[dict[str, np.ndarray]]:
        """Yield ``{column: contiguous array}`` for consecutive runs of at most ``size`` points.

        Parameters
        ----------
        columns
            Which columns (default: all of :attr:`fields`).
        size
            Points per chunk; every chunk but the last has exactly this many.
        """

    def metadata_json(self) -> str:
        """The frame metadata as one line of compact JSON."""
        return frame_metadata_json(self.frame)

    def records(self) -> np.ndarray | None:
        """Every point as one structured array of :attr:`fields` (in that order), if the
        source holds them so; else ``None`` (read them with :meth:`iter_chunks`). Exporters
        may convert it in one call instead of column by column; it is not to be modified."""
        return None

    def to_cloud(self) -> PointCloud:
        """All points in memory as a :class:`PointCloud` (for exporters that cannot stream)."""
        columns = {name: np.empty(0, dtype=dtype) for name, dtype in self.fields.items()}
        for chunk in self.iter_chunks(size=max(len(self), 1)):
            columns = chunk  # one chunk holds every point
        return PointCloud(columns, self.frame)


class CloudPoints(PointSource):
    """A :class:`PointSource` over an in-memory :class:`PointCloud` (chunks are slices)."""

    def __init__(self, cloud: PointCloud) -> None:
        self.cloud = cloud
        self.frame = cloud.frame
        self._fields = column_dtypes(cloud.columns)

    def __len__(self) -> int:
        return len(self.cloud)

    @property
    def fields(self) -> dict[str, np.dtype]:
        return dict(self._fields)

    def iter_chunks(self, columns: Sequence[str] | None = None,
                    size: int = DEFAULT_CHUNK_POINTS) -> Iterator[dict[str, np.ndarray]]:
        names = list(columns) if columns is not None else list(self._fields)
        n = len(self)
        for start in range(0, n, size):
            yield {name: np.ascontiguousarray(self.cloud.columns[name][start:start + size],
                                              dtype=self._fields[name]) for name in names}

    def to_cloud(self) -> PointCloud:
        return self.cloud


class PointSpool(PointSource):
    """Collects a frame's point chunks, in memory up to ``memory_limit`` bytes, then on disk.

    Use as a context manager (or call :meth:`close`) so the temporary file goes away; it is
    created already unlinked, so not even a killed process leaves it behind.

    Parameters
    ----------
    frame
        Metadata of the frame being collected.
    memory_limit
        Bytes of records kept in memory before everything moves to a temporary file.
    tmp_dir
        Directory of that file (default: the system's temporary directory, ``TMPDIR``).
    """

    def __init__(self, frame: FrameInfo, *, memory_limit: int = DEFAULT_SPOOL_MEMORY,
                 tmp_dir: str | None = None) -> None:
        self.frame = frame
        self.memory_limit = memory_limit
        self.tmp_dir = tmp_dir
        self._dtype: np.dtype | None = None
        self._parts: list[dict[str, np.ndarray]] = []
        self._held = 0
        self._count = 0
        self._file: IO[bytes] | None = None
        self._joined: np.ndarray | None = None

    @classmethod
    def from_records(cls, frame: FrameInfo, records: np.ndarray) -> "PointSpool":
        """A spool holding ``records`` (a structured array of a frame's points, as
        :meth:`records` returns them) as they are, without a copy."""
        spool = cls(frame, memory_limit=max(records.nbytes, DEFAULT_SPOOL_MEMORY))
        if len(records):
            spool.append({name: records[name] for name in records.dtype.names or ()})
            spool._joined = records  # what the parts make, already made
        return spool

    # ---- collecting ---------------------------------------------------------------------
    def append(self, columns: dict[str, np.ndarray]) -> None:
        """Add one chunk of columns (the same columns every time)."""
        fields = column_dtypes(columns)
        if self._dtype is None:
            self._dtype = np.dtype(list(fields.items()))
        elif list(fields) != list(self._dtype.names or ()):
            raise ValueError("every chunk must have the same columns")
        n = len(columns[next(iter(fields))]) if fields else 0
        if any(len(columns[name]) != n for name in fields):
            raise ValueError("every column of a chunk must have the same length")
        if n == 0:
            return
        self._joined = None
        self._count += n
        size = n * self._dtype.itemsize
        if self._file is None and self._held + size <= self.memory_limit:
            # the chunk's arrays as they are: made into records when they are read, by the
            # thread that writes them (a dataset's writer, not the simulating thread)
            self._parts.append({name: columns[name] for name in fields})
            self._held += size
            return
        if self._file is None:
            self._file = tempfile.TemporaryFile(prefix="lidarsim-spool-", dir=self.tmp_dir)
            for part in self._parts:
                self._file.write(self._records([part]).tobytes())
            self._parts, self._held = [], 0
        self._file.seek(0, 2)
        self._file.write(self._records([columns]).tobytes())

    def _records(self, parts: list[dict[str, np.ndarray]]) -> np.ndarray:
        """One structured array of ``parts``' columns (each converted to the spool's
        dtype as an assignment converts it)."""
        assert self._dtype is not None
        records = np.empty(sum(len(next(iter(p.values()))) for p in parts), dtype=self._dtype)
        start = 0
        for part in parts:
            n = len(next(iter(part.values())))
            for name, values in part.items():
                records[name][start:start + n] = values
            start += n
        return records

    def extend(self, chunks: Iterable[dict[str, np.ndarray]]) -> "PointSpool":
        """Append every chunk of ``chunks``; returns ``self``."""
        for chunk in chunks:
            self.append(chunk)
        return self

    @property
    def spilled(self) -> bool:
        """Whether the records moved to a temporary file."""
        return self._file is not None

    # ---- reading ------------------------------------------------------------------------
    def __len__(self) -> int:
        return self._count

    @property
    def fields(self) -> dict[str, np.dtype]:
        if self._dtype is None:
            return {k: np.dtype(v) for k, v in POINT_FIELDS.items()}
        return {name: self._dtype.fields[name][0] for name in self._dtype.names or ()}

    def iter_chunks(self, columns: Sequence[str] | None = None,
                    size: int = DEFAULT_CHUNK_POINTS) -> Iterator[dict[str, np.ndarray]]:
        if size < 1:
            raise ValueError("chunk size must be positive")
        names = list(columns) if columns is not None else list(self.fields)
        if self._count == 0 or self._dtype is None:
            return
        if self._file is None:
            records = self.records()
            assert records is not None
            for start in range(0, self._count, size):
                block = records[start:start + size]
                yield {name: np.ascontiguousarray(block[name]) for name in names}
            return
        itemsize = self._dtype.itemsize
        for start in range(0, self._count, size):
            n = min(size, self._count - start)
            self._file.seek(start * itemsize)
            block = np.frombuffer(self._file.read(n * itemsize), dtype=self._dtype)
            yield {name: np.ascontiguousarray(block[name]) for name in names}

    @property
    def record_dtype(self) -> np.dtype | None:
        """The structured dtype of the records (:attr:`fields`), ``None`` before the first
        chunk."""
        return self._dtype

    def parts(self) -> list[dict[str, np.ndarray]] | None:
        """The chunks appended (their columns in :attr:`fields` order, each as it was
        given: the dtype may differ from the field's), while they are held in memory; else
        ``None``. For a writer elsewhere that joins them itself; not to be modified."""
        if self._file is not None or self._dtype is None:
            return None
        return list(self._parts)

    def records(self) -> np.ndarray | None:
        if self._file is not None or self._dtype is None:
            return None
        if self._joined is None:
            self._joined = self._records(self._parts)
        return self._joined

    def close(self) -> None:
        """Release the memory and the temporary file."""
        if self._file is not None:
            self._file.close()
            self._file = None
        self._parts, self._joined, self._held, self._count = [], None, 0, 0

    def __enter__(self) -> "PointSpool":
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
