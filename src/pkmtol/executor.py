"""One executor for the embarrassingly parallel loops: in-process, local processes, or a Dask cluster.

The loops that repeat independent work (exact verification, the claimed-vs-true reliabilities, a
sweep over design variants, a calibration study's machines) are written as a module-level function
applied to a list of chunks: :func:`map_chunks` runs it serially, on ``workers`` local processes or on
Dask distributed workers and returns the results in chunk order. A chunk's content never depends on
the executor, and randomness inside a chunk comes from :func:`chunk_seeds` (one seed per chunk, not
per worker), so every executor and worker count gives bit-identical results.

Local processes are started with ``fork`` where the platform has it (no re-import of Pinocchio in
each worker) and kept for the life of the process; so is a Dask client. Serial is the default: for
the default jobs (about a second of work) starting processes and pickling the mechanism costs more
than the second core gives back, and the machines pkmtol is tested on are shared (docs/scale.md).

>>> map_chunks(abs, [-1, 2, -3])
[1, 2, 3]
>>> [s.generate_state(1)[0] for s in chunk_seeds(0, 2)] == [s.generate_state(1)[0] for s in chunk_seeds(0, 2)]
True
"""

from __future__ import annotations

import atexit
import contextlib
import ctypes
import multiprocessing
import os
import signal
import threading
import time
from collections.abc import Callable, Iterable, Iterator
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass
from typing import Any, TypeVar

import numpy as np

from pkmtol.exceptions import ExecutorError

T = TypeVar("T")
R = TypeVar("R")

#: Seconds to wait for a Dask scheduler before giving up.
DASK_TIMEOUT_S = 10.0


@dataclass(frozen=True)
class Executor:
    """Where :func:`map_chunks` runs its chunks.

    Attributes:
        workers: Local processes; 1 = serial, in this process. With ``dask="local"``: the number of
            workers of the ``LocalCluster`` (1: one per core).
        dask: A Dask scheduler address (``tcp://host:8786``), or ``"local"`` to start a
            ``LocalCluster`` on this machine; None: no Dask. Needs ``pip install 'pkmtol[dask]'``.

    Raises:
        ExecutorError: ``workers`` is not an integer ≥ 1, or ``dask`` is an empty string.
    """

    workers: int = 1
    dask: str | None = None

    def __post_init__(self) -> None:
        if (
            isinstance(self.workers, bool)
            or not isinstance(self.workers, int | np.integer)
            or self.workers < 1
        ):
            raise ExecutorError(
                "workers",
                f"{self.workers!r} is not a number of processes; "
                "give an integer ≥ 1 (1 = serial, in this process)",
            )
        if self.dask is not None and not str(self.dask).strip():
            raise ExecutorError(
                "dask", "empty scheduler address; give 'local' or an address such as tcp://host:8786"
            )

    @property
    def parallel(self) -> bool:
        """True when chunks run outside this process."""
        return self.dask is not None or self.workers > 1

    def connect(self) -> Executor:
        """Reach the Dask scheduler now (start the LocalCluster), so a bad address fails before any work.

        Raises:
            ExecutorError: the Dask extra is missing or no scheduler answers at the address.
        """
        if self.dask is not None:
            _dask_client(self)
        return self

    def describe(self) -> str:
        """One line for reports: ``serial``, ``2 local processes`` or ``Dask at tcp://…``."""
        if self.dask == "local":
            return f"Dask LocalCluster ({self.workers if self.workers > 1 else os.cpu_count()} workers)"
        if self.dask is not None:
            return f"Dask scheduler {self.dask}"
        return "serial" if self.workers == 1 else f"{self.workers} local processes"


def map_chunks(fn: Callable[[T], R], items: Iterable[T], executor: Executor | None = None) -> list[R]:
    """``[fn(item) for item in items]``, run by ``executor``, results in item order.

    Args:
        fn: A module-level (picklable) function of one chunk; it must not rely on state of this
            process other than what ``item`` carries.
        items: The chunks (picklable when the executor is parallel).
        executor: Where to run (None: serial).

    Raises:
        ExecutorError: the Dask extra is not installed, or its scheduler cannot be reached.
        Whatever ``fn`` raises for the first chunk (in item order) that fails.
    """
    return list(imap_chunks(fn, items, executor))


def imap_chunks(fn: Callable[[T], R], items: Iterable[T], executor: Executor | None = None) -> Iterator[R]:
    """:func:`map_chunks` as an iterator: each result as soon as it and those before it are done.

    All chunks are submitted at once (a parallel executor works ahead of the consumer); the
    results still come in item order (for progress bars over long jobs).
    """
    ex = executor or Executor()
    chunks = list(items)
    if not chunks:
        return iter(())
    if ex.dask is not None:
        client = _dask_client(ex)
        futures = client.map(fn, chunks, pure=False)
        return (f.result() for f in futures)
    if ex.workers == 1 or len(chunks) == 1:
        return (fn(c) for c in chunks)
    return _process_pool(ex.workers).map(fn, chunks)


def chunk_seeds(seed: int, n_chunks: int) -> list[np.random.SeedSequence]:
    """Independent seeds for chunks ``0 … n_chunks−1`` of a job seeded with ``seed``.

    Chunk ``k`` gets the same seed whatever the executor and the number of workers
    (``SeedSequence(seed).spawn(n_chunks)[k]``); use ``np.random.default_rng(seeds[k])`` inside
    the chunk.

    Raises:
        ExecutorError: ``n_chunks`` is negative.
    """
    if n_chunks < 0:
        raise ExecutorError("n_chunks", f"{n_chunks} chunks; give a count ≥ 0")
    return np.random.SeedSequence(seed).spawn(n_chunks)


# --- pools and clients, kept for the life of the process ------------------------------------

_POOLS: dict[int, ProcessPoolExecutor] = {}
_CLIENTS: dict[tuple[str, int], Any] = {}


def _process_pool(workers: int) -> ProcessPoolExecutor:
    pool = _POOLS.get(workers)
    if pool is None:
        methods = multiprocessing.get_all_start_methods()
        context = multiprocessing.get_context("fork" if "fork" in methods else None)
        pool = ProcessPoolExecutor(
            max_workers=workers, mp_context=context, initializer=_worker_init, initargs=(os.getpid(),)
        )
        _POOLS[workers] = pool
    return pool


#: Seconds between a worker's checks that its parent is still alive (the portable watchdog).
WATCHDOG_S = 0.5
#: Linux prctl option: the signal a process gets when its parent dies.
_PR_SET_PDEATHSIG = 1


def _worker_init(parent_pid: int) -> None:
    """A local worker: leave Ctrl-C to the parent (which stops the pool) and die with the parent.

    On Linux the kernel sends the worker SIGTERM when its parent dies (``PR_SET_PDEATHSIG`` via
    ``prctl``); everywhere, a daemon thread exits the worker once its parent is gone (its parent
    pid changes), so that no worker outlives a killed ``pkmtol`` (issue 25).
    """
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, signal.SIG_DFL)
    with contextlib.suppress(OSError, AttributeError):
        libc = ctypes.CDLL(None, use_errno=True)
        libc.prctl(_PR_SET_PDEATHSIG, int(signal.SIGTERM), 0, 0, 0)
    if os.getppid() != parent_pid:  # the parent died before the signal was armed
        os._exit(1)
    threading.Thread(target=_watch_parent, args=(parent_pid,), daemon=True, name="pkmtol-watchdog").start()


def _watch_parent(parent_pid: int) -> None:
    while os.getppid() == parent_pid:
        time.sleep(WATCHDOG_S)
    os._exit(1)


def abort() -> None:
    """Stop every kept pool and Dask client now, without waiting for their work (on a signal or error).

    The pools' processes are terminated (then killed if they linger); Dask clients and local
    clusters are closed with a short timeout.
    """
    for pool in list(_POOLS.values()):
        processes = list(getattr(pool, "_processes", {}).values())
        pool.shutdown(wait=False, cancel_futures=True)
        for p in processes:
            with contextlib.suppress(Exception):
                p.terminate()
        for p in processes:
            with contextlib.suppress(Exception):
                p.join(timeout=2.0)
                if p.is_alive():
                    p.kill()
        _forget_wakeup(pool)
    _POOLS.clear()
    for client in list(_CLIENTS.values()):
        cluster = getattr(client, "cluster", None)
        with contextlib.suppress(Exception):
            client.close(timeout=2)
        if cluster is not None:
            with contextlib.suppress(Exception):
                cluster.close(timeout=2)
    _CLIENTS.clear()


def _forget_wakeup(pool: Any) -> None:
    """Let a terminated pool's manager thread finish, then drop its wake-up pipe from the exit hook.

    ``concurrent.futures`` writes to every pool's wake-up pipe at interpreter exit. After
    :func:`abort` the manager thread closes that pipe as it winds down, and on Python 3.11 the
    exit hook's write then races the close and prints "Exception ignored ... Bad file descriptor"
    after pkmtol's one line. Joining the thread and forgetting its pipe removes the race.
    """
    from concurrent.futures import process as cf_process

    thread = getattr(pool, "_executor_manager_thread", None)
    if thread is None:
        return
    with contextlib.suppress(Exception):
        thread.join(timeout=2.0)
    if not thread.is_alive():  # a live thread still needs the exit hook's wake-up
        with contextlib.suppress(Exception):
            cf_process._threads_wakeups.pop(thread, None)


def _dask_client(ex: Executor) -> Any:
    assert ex.dask is not None
    key = (ex.dask, ex.workers)
    client = _CLIENTS.get(key)
    if client is not None:
        return client
    try:
        from dask.distributed import Client, LocalCluster
    except ImportError as err:
        raise ExecutorError(
            "dask",
            f"Dask distributed is not installed ({err}); install it with `pip install 'pkmtol[dask]'`",
        ) from err
    if ex.dask == "local":
        n = ex.workers if ex.workers > 1 else (os.cpu_count() or 1)
        cluster = LocalCluster(n_workers=n, threads_per_worker=1, processes=True, dashboard_address=None)
        client = Client(cluster)
    else:
        _probe(ex.dask)
        try:
            client = Client(ex.dask, timeout=DASK_TIMEOUT_S)
        except (OSError, TimeoutError, ValueError) as err:
            raise ExecutorError(
                "dask",
                f"no Dask scheduler answers at {ex.dask!r} within {DASK_TIMEOUT_S:g} s ({err}); start one "
                "with `dask scheduler` and workers with `dask worker <address>` (docs/scale.md), "
                "or give --dask local",
            ) from err
    _CLIENTS[key] = client
    return client


#: The largest first message a Dask scheduler sends (its handshake: a few hundred bytes).
_HANDSHAKE_BYTES = 1 << 20


def _probe(address: str) -> None:
    """Check that a Dask scheduler speaks at a ``tcp://`` address within :data:`DASK_TIMEOUT_S`.

    A scheduler writes its handshake as soon as a connection opens (8 bytes of length, then the
    message). A server that accepts and stays silent would hang ``Client`` far beyond its
    timeout, and one that speaks another protocol made it allocate a "frame" of the length its
    first bytes spell (an out-of-memory error): both are refused here, naming what was found.

    Raises:
        ExecutorError: no connection, no answer in time, or an answer that is not Dask's.
    """
    import socket
    import struct

    text = address.removeprefix("tcp://")
    if "://" in text:
        return  # tls://, ucx://, inproc://: left to Dask
    host, _, port = text.rpartition(":")
    try:
        port_no = int(port)
    except ValueError:
        raise ExecutorError("dask", f"{address!r} is not host:port; give e.g. tcp://host:8786") from None
    deadline = time.monotonic() + DASK_TIMEOUT_S
    try:
        with socket.create_connection(
            (host.strip("[]") or "localhost", port_no), timeout=DASK_TIMEOUT_S
        ) as sock:
            head = b""
            while len(head) < 8:
                sock.settimeout(max(deadline - time.monotonic(), 0.01))
                chunk = sock.recv(8 - len(head))
                if not chunk:
                    break
                head += chunk
    except TimeoutError:
        raise ExecutorError(
            "dask",
            f"the server at {address!r} accepts connections but sent no Dask handshake within "
            f"{DASK_TIMEOUT_S:g} s; is it a Dask scheduler (`dask scheduler`)? (docs/scale.md)",
        ) from None
    except OSError as err:
        raise ExecutorError(
            "dask",
            f"no Dask scheduler answers at {address!r} ({err.strerror or err}); start one with "
            "`dask scheduler` and workers with `dask worker <address>` (docs/scale.md), or give --dask local",
        ) from err
    (size,) = struct.unpack("<Q", head) if len(head) == 8 else (-1,)
    if not 0 < size <= _HANDSHAKE_BYTES:
        raise ExecutorError(
            "dask",
            f"the server at {address!r} is not a Dask scheduler (its first bytes {head[:8]!r} are not "
            "a Dask handshake); check the address and port (a scheduler listens on 8786 by default)",
        )


@atexit.register
def shutdown() -> None:
    """Stop the kept process pools and Dask clients (also run at exit)."""
    for pool in _POOLS.values():
        pool.shutdown(wait=True, cancel_futures=True)
    _POOLS.clear()
    for client in _CLIENTS.values():
        cluster = getattr(client, "cluster", None)
        client.close()
        if cluster is not None:
            cluster.close()
    _CLIENTS.clear()
