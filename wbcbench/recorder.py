"""Per-tick run log: a columnar Parquet file written in row groups as the run goes, so a run that fails or is
interrupted keeps its log up to the last flushed group (and `close()` flushes the rest)."""

from __future__ import annotations

import os
import threading
from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq


class Recorder:
    """Register channels (name -> component labels) once, then fill one row per tick and `commit()` it.

    Column names are `channel` for scalars or `channel.component`. Values are float64. Rows are flushed to the
    file `chunk` at a time (a row group each): a row group costs a fixed amount per column besides its values, so
    larger groups cost less per tick (a third less at 3,000 rows than at 1,000, on a 200-column walk log); a run
    that raises or is interrupted still flushes what it has (`close`), only a killed process loses the rows
    since the last group.
    """

    def __init__(self, path: str | Path, chunk: int = 4000):
        self.path = Path(path)
        self.chunk = chunk
        self.columns: list[str] = []
        self.slices: dict[str, slice] = {}
        self._buf: np.ndarray | None = None
        self._spare: np.ndarray | None = None  # the other buffer, while a flushed one is being written
        self._n = 0
        self._writer: pq.ParquetWriter | None = None
        self._pending: threading.Thread | None = None
        self._pending_error: BaseException | None = None
        self.rows_written = 0

    def add_channel(self, name: str, components: list[str] | None = None) -> slice:
        if self._buf is not None:
            raise RuntimeError("channels must be added before the first row")
        if name in self.slices:
            raise ValueError(f"channel '{name}' registered twice")
        start = len(self.columns)
        if components:
            self.columns += [f"{name}.{c}" for c in components]
        else:
            self.columns.append(name)
        self.slices[name] = slice(start, len(self.columns))
        return self.slices[name]

    @property
    def row(self) -> np.ndarray:
        """The row being filled (write into it with the slices returned by add_channel)."""
        if self._buf is None:
            # column-major: each column of a flushed block is contiguous and goes to Arrow without a copy
            self._buf = np.full((self.chunk, len(self.columns)), np.nan, order="F")
        return self._buf[self._n]

    def commit(self) -> None:
        self.row  # noqa: B018  (allocates on first use)
        self._n += 1
        if self._n == self.chunk:
            self.flush()

    def flush(self, wait: bool = False) -> None:
        """Write the rows filled so far as a row group. The compression and the file write run in a thread
        (pyarrow releases the GIL there), so that a paced run does not stall for the tens of milliseconds a
        group takes; the next flush (or `close`, or `wait=True`) waits for it and raises its error (a full disk)."""
        self._join()
        if self._buf is None or self._n == 0:
            return
        block = self._buf[: self._n]
        # zero-copy columns of the column-major buffer: it is not reused before the write is done
        table = pa.Table.from_arrays([pa.array(block[:, i]) for i in range(block.shape[1])], names=self.columns)
        if self._writer is None:
            self.path.parent.mkdir(parents=True, exist_ok=True)
            # no dictionary encoding: float channels almost never repeat, and trying costs half the write time
            self._writer = pq.ParquetWriter(self.path, table.schema, compression="zstd", use_dictionary=False)
        n, self._n = self._n, 0
        self._buf, self._spare = (self._spare, self._buf)
        if self._buf is None:
            self._buf = np.full((self.chunk, len(self.columns)), np.nan, order="F")
        else:
            self._buf[:] = np.nan
        self._pending = threading.Thread(target=self._write, args=(table, n), name="wbcbench-log-writer", daemon=True)
        self._pending.start()
        if wait:
            self._join()

    def _write(self, table: pa.Table, n: int) -> None:
        # below the run's thread: on a core it shares with the loop (a pinned run) the write takes the time the
        # loop leaves (a paced run sleeps between ticks) instead of delaying ticks by a group's write
        try:
            os.setpriority(os.PRIO_PROCESS, threading.get_native_id(), 19)
        except (AttributeError, OSError):  # no per-thread priority here: the write runs as it is
            pass
        try:
            self._writer.write_table(table)
            self.rows_written += n
        except BaseException as exc:  # raised in the caller's thread by the next flush or close
            self._pending_error = exc

    def _join(self) -> None:
        if self._pending is not None:
            self._pending.join()
            self._pending = None
        if self._pending_error is not None:
            exc, self._pending_error = self._pending_error, None
            raise exc

    def close(self) -> None:
        """Flush the pending rows and finish the file. If a write fails (a full disk), the file is still
        finished with the rows written before, and the error raised."""
        try:
            self.flush(wait=True)
        finally:
            if self._pending is not None:  # the flush raised before waiting for the write it started
                self._pending.join()
                self._pending = None
            if self._writer is not None:
                writer, self._writer = self._writer, None
                writer.close()


def read_log(path: str | Path) -> dict[str, np.ndarray]:
    """Read a run log into {column: array}."""
    table = pq.read_table(path)
    return {name: table.column(name).to_numpy() for name in table.column_names}


def channel(log: dict[str, np.ndarray], name: str) -> np.ndarray:
    """All columns of a channel stacked as (ticks, components), in their recorded order."""
    cols = [k for k in log if k == name or k.startswith(name + ".")]
    if not cols:
        raise KeyError(f"no channel '{name}' in the log")
    return np.column_stack([log[c] for c in cols])
