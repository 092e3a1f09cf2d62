"""Where cells run: in this process (1 job), a local process pool, or Ray (a local instance or a cluster), behind
one interface: `executor.map_unordered(fn, kwargs_list)` yields (index, result) as tasks finish."""

from __future__ import annotations

import socket
from collections.abc import Callable, Iterator, Sequence
from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait
from multiprocessing import get_context

from ..errors import ConfigError


class Executor:
    """Base: run in this process, one task after the other."""

    name = "inline"
    workers = 1

    def map_unordered(self, fn: Callable, kwargs_list: Sequence[dict]) -> Iterator[tuple[int, object]]:
        for i, kw in enumerate(kwargs_list):
            yield i, fn(**kw)

    def close(self) -> None:
        pass

    def __enter__(self):
        return self

    def __exit__(self, *exc) -> None:
        self.close()


class PoolExecutor(Executor):
    """A local process pool of `jobs` workers (spawned, so workers hold no state of the parent)."""

    name = "pool"

    def __init__(self, jobs: int):
        self.workers = jobs
        self._pool = ProcessPoolExecutor(max_workers=jobs, mp_context=get_context("spawn"))

    def map_unordered(self, fn, kwargs_list):
        futures = {self._pool.submit(fn, **kw): i for i, kw in enumerate(kwargs_list)}
        pending = set(futures)
        while pending:
            done, pending = wait(pending, return_when=FIRST_COMPLETED)
            for f in done:
                yield futures[f], f.result()

    def close(self) -> None:
        self._pool.shutdown(wait=True, cancel_futures=True)


def _check_reachable(address: str) -> None:
    """Fail in a second (ConfigError) when nothing listens at a host:port address, instead of Ray's long retry."""
    hostport = address.split("://", 1)[-1]
    host, _, port = hostport.rpartition(":")
    if not host or not port.isdigit():
        raise ConfigError(f"Ray address '{address}' is not HOST:PORT (or 'auto' for a local instance)", key="--ray")
    try:
        socket.create_connection((host, int(port)), timeout=3.0).close()
    except OSError as exc:
        raise ConfigError(f"cannot reach a Ray cluster at '{address}' ({exc.strerror or exc})", key="--ray") \
            from None


class RayExecutor(Executor):
    """Ray: `address` 'auto' starts a local instance with `jobs` CPUs (or uses the one already initialised in this
    process); HOST:PORT connects to a running cluster (`ray start --head`). One CPU per task."""

    name = "ray"

    def __init__(self, address: str, jobs: int | None = None):
        try:
            import ray
        except ImportError:
            raise ConfigError("Ray is not installed; pip install 'wbcbench[ray]'", key="--ray") from None
        self._ray = ray
        self._started = False
        if not ray.is_initialized():
            if address == "auto":
                import os
                env = {"PYTHONPATH": os.environ["PYTHONPATH"]} if os.environ.get("PYTHONPATH") else {}
                ray.init(num_cpus=jobs, include_dashboard=False, log_to_driver=False,
                         runtime_env={"env_vars": env} if env else None)
            else:
                _check_reachable(address)
                try:
                    ray.init(address=address, log_to_driver=False)
                except Exception as exc:
                    raise ConfigError(f"cannot connect to Ray at '{address}': {exc}".splitlines()[0],
                                      key="--ray") from None
            self._started = True
        self.workers = int(ray.cluster_resources().get("CPU", 1))

    def map_unordered(self, fn, kwargs_list):
        ray = self._ray
        remote = ray.remote(num_cpus=1)(fn)
        refs = {remote.remote(**kw): i for i, kw in enumerate(kwargs_list)}
        pending = list(refs)
        while pending:
            done, pending = ray.wait(pending, num_returns=1)
            for r in done:
                yield refs[r], ray.get(r)

    def close(self) -> None:
        if self._started:
            self._ray.shutdown()


def make_executor(jobs: int = 1, ray: str | None = None) -> Executor:
    """The executor for the CLI's `--jobs N` / `--ray ADDRESS|auto`."""
    if jobs < 1:
        raise ConfigError(f"--jobs must be >= 1, got {jobs}", key="--jobs")
    if ray:
        return RayExecutor(ray, jobs if ray == "auto" else None)
    return PoolExecutor(jobs) if jobs > 1 else Executor()
