"""Per-tick run log: a columnar Parquet file written in row groups as the run goes, so a run that fails or is
interrupted keeps its log up to the last flushed group (and `close()` flushes the rest)."""

from __future__ import annotations

import os
import queue
import threading
from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq

from .jit import JIT_ENABLED, njit


@njit
def _columns_and_reset(block, columns, base):
    """``columns[:] = block`` (``columns`` Fortran-ordered: each column contiguous for Arrow), then ``base`` (the
    buffer ``block`` is the first rows of) all NaN, in tiles, without the interpreter's lock: numpy's
    ``asfortranarray`` and fill hold it for their whole 5-9 ms on a 4,000-row group, and a paced loop waiting
    for it then missed its tick."""
    n, k = block.shape
    T = 32
    for i0 in range(0, n, T):
        i1 = min(i0 + T, n)
        for j0 in range(0, k, T):
            j1 = min(j0 + T, k)
            for j in range(j0, j1):
                for i in range(i0, i1):
                    columns[i, j] = block[i, j]
    nan = np.nan
    for i in range(base.shape[0]):
        for j in range(base.shape[1]):
            base[i, j] = nan


# the file's encoding. No dictionary encoding: float channels almost never repeat, and trying costs half the write
# time; the floats' bytes split into streams (exponents together) then LZ4: measured on a walk log, 7.4 MB in
# 1.9 us per row, against 8.9 MB in 3.3 us with zstd on the plain floats
_PARQUET_OPTIONS = dict(compression="lz4", use_dictionary=False, use_byte_stream_split=True)
_warmed_up = False


def _warm_up_writes() -> None:
    """Run a row group's whole write path once in this process, on a tiny table in memory: the compiled pass
    loaded, Arrow's conversions, encoders and codec initialised. Done lazily at the first row group, in the
    writer thread, that one-off work held the interpreter's lock for 12-30 ms and a paced loop missed its ticks."""
    global _warmed_up
    if _warmed_up:
        return
    block = np.zeros((2, 2))
    table, _ = _arrow_table(block, block, ["a", "b"])
    with pq.ParquetWriter(pa.BufferOutputStream(), table.schema, **_PARQUET_OPTIONS) as writer:
        writer.write_table(table)
    _warmed_up = True


def _arrow_table(block: np.ndarray, base: np.ndarray, names: list[str]) -> tuple[pa.Table, bool]:
    """A row group's rows as an Arrow table of its columns, and whether ``base`` (the buffer ``block`` is the
    first rows of) was reset to NaN on the way (compiled: the copy and the reset without holding the interpreter's
    lock)."""
    if JIT_ENABLED:
        columns = np.empty(block.shape, order="F")
        _columns_and_reset(block, columns, base)
        reset = True
    else:
        columns = np.asfortranarray(block)  # each column contiguous: Arrow takes them without a copy
        reset = False
    return pa.Table.from_arrays([pa.array(columns[:, i]) for i in range(columns.shape[1])], names=names), reset


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
        # one writer thread for the run (made with the first row: starting a thread at a flush took the loop 2-5 ms)
        self._queue: queue.Queue | None = None
        self._worker: threading.Thread | None = None
        self._worker_pid: int | None = None
        self._busy = False  # a block handed to the writer and not yet written
        self._pending_error: BaseException | None = None
        self._derived: list = []
        self._handed = 0  # rows handed to the writer thread so far
        self.rows_written = 0

    def derive(self, fill) -> None:
        """Columns computed once per row group instead of once per tick: ``fill(block, first)`` writes them into
        the flushed rows (an (n, columns) float64 array, row-major; ``first`` the index of its first row in the
        log), in the writer thread before the write (e.g. a compiled pass that releases the GIL, or a copy of
        what the caller kept per row). Its errors surface like a failed write."""
        self._derived.append(fill)

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
            # row-major: a tick's writes land in one contiguous row (a few cache lines) rather than one line
            # and one page per column; the writer thread transposes a flushed block for Arrow. Both buffers
            # now, their pages touched: a paced run does not stall at its first flush
            shape = (self.chunk, len(self.columns))
            self._buf, self._spare = np.full(shape, np.nan), np.full(shape, np.nan)
            _warm_up_writes()
            self._start_worker()
        return self._buf[self._n]

    def commit(self) -> np.ndarray:
        """Keep the row filled and return the next one (the same as `row` then)."""
        if self._buf is None:
            self.row  # noqa: B018  (allocates on first use)
        n = self._n = self._n + 1
        if n == self.chunk:
            self.flush()
            n = 0
        return self._buf[n]

    def flush(self, wait: bool = False) -> None:
        """Write the rows filled so far as a row group. The compression and the file write run in a thread
        (pyarrow releases the GIL there), so that a paced run does not stall for the tens of milliseconds a
        group takes; the next flush (or `close`, or `wait=True`) waits for it and raises its error (a full disk)."""
        self._join()
        if self._buf is None or self._n == 0:
            return
        # the filled rows; not reused before the write is done (the other buffer is filled meanwhile)
        block = self._buf[: self._n]
        n, self._n = self._n, 0
        first, self._handed = self._handed, self._handed + n
        self._buf, self._spare = (self._spare, self._buf)
        # the writer thread opens the file (first group), writes the block, then resets its buffer (the next one
        # filled) to NaN
        if self._worker is None or self._worker_pid != os.getpid():  # none yet, or this is a forked copy
            self._start_worker()
        self._busy = True
        self._queue.put((block, n, first))
        if wait:
            self._join()

    def _start_worker(self) -> None:
        self._queue = queue.Queue()
        self._busy = False
        self._worker = threading.Thread(target=self._work, args=(self._queue,), name="wbcbench-log-writer",
                                        daemon=True)
        self._worker_pid = os.getpid()
        self._worker.start()

    #: the writer thread's scheduling: None for the normal class at the lowest priority (nice 19), or a real-time
    #: (SCHED_FIFO) priority, below the run's thread, for a run whose loop is in the real-time class (`set_writer_priority`)
    writer_priority: int | None = None

    def set_writer_priority(self, priority: int | None) -> None:
        """The writer thread's scheduling (`writer_priority`), now if it runs, else when it starts."""
        self.writer_priority = priority
        if self._worker is not None and self._worker.is_alive():
            self._apply_priority(self._worker.native_id)

    def _apply_priority(self, tid: int) -> None:
        # always below the run's thread: on a core it shares with the loop (a pinned run) the write takes the time
        # the loop leaves (a paced run sleeps between ticks) instead of delaying ticks by a group's write. A
        # writer that inherited the loop's real-time priority would run a whole group (30-60 ms) before the loop
        # could take the core back; one in the normal class under a real-time loop waits behind the machine's
        # other threads while it holds the interpreter's lock the loop needs
        try:
            if self.writer_priority is not None:
                os.sched_setscheduler(tid, os.SCHED_FIFO, os.sched_param(self.writer_priority))
                return
            if os.sched_getscheduler(tid) != os.SCHED_OTHER:
                os.sched_setscheduler(tid, os.SCHED_OTHER, os.sched_param(0))
            os.setpriority(os.PRIO_PROCESS, tid, 19)
        except (AttributeError, OSError):  # no per-thread scheduling here: the write runs as it is
            pass

    def _work(self, jobs: queue.Queue) -> None:
        self._apply_priority(threading.get_native_id())
        while True:
            job = jobs.get()
            try:
                if job is None:
                    return
                self._write(*job)
            finally:
                jobs.task_done()

    def _write(self, block: np.ndarray, n: int, first: int) -> None:
        reset = False
        try:
            if self._writer is None:
                self.path.parent.mkdir(parents=True, exist_ok=True)
                schema = pa.schema([(name, pa.float64()) for name in self.columns])
                self._writer = pq.ParquetWriter(self.path, schema, **_PARQUET_OPTIONS)
            for fill in self._derived:
                fill(block, first)
            table, reset = _arrow_table(block, block.base, self.columns)
            self._writer.write_table(table)
            self.rows_written += n
        except BaseException as exc:  # raised in the caller's thread by the next flush or close
            self._pending_error = exc
        finally:
            if not reset:
                block.base[:] = np.nan  # rows a tick leaves unwritten are NaN in the file

    def _join(self) -> None:
        if self._busy:
            if self._worker_pid == os.getpid():
                self._queue.join()
            self._busy = False
        if self._pending_error is not None:
            exc, self._pending_error = self._pending_error, None
            raise exc

    def close(self) -> None:
        """Flush the pending rows and finish the file. If a write fails (a full disk), the file is still
        finished with the rows written before, and the error raised."""
        try:
            self.flush(wait=True)
        finally:
            if self._worker is not None and self._worker_pid == os.getpid():
                self._queue.join()  # the flush may have raised before waiting for the write it handed over
                self._queue.put(None)
                self._worker.join()
            self._worker, self._busy = None, False
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
