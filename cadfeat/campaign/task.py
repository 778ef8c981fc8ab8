"""What a Dask worker runs for one case: ``run_case(payload)`` — one study, exactly as ``cadfeat run``.

The payload is plain data (the resolved study dict, the output folder, the time limit, the expected file
hashes): no CAD object crosses the network. The worker checks that it reads the same part / calibration /
CSV bytes as the machine that planned the campaign (a shared folder with the same paths), then calls
``cadfeat.study.run_study`` into the case's folder (staged and published by the study layer: a case stopped
for any reason leaves no half-written folder) and returns an outcome dict; it never raises for a failing study.

Time limit: a watchdog thread raises ``CaseTimeout`` (a ``BaseException``, so no ``except Exception`` in the
study swallows it) in the study's thread when ``timeout_s`` has passed (``PyThreadState_SetAsyncExc``; it is
delivered at the next Python bytecode, so at the latest when a running CAD build returns — those have their
own limit, ``[study] build_timeout_s``). A study stuck longer in C code is stopped by the campaign, which
restarts the worker (``cadfeat.campaign.runner``).
"""

from __future__ import annotations

import contextlib
import ctypes
import multiprocessing
import os
import socket
import threading
import time
from collections.abc import Iterator, Mapping
from typing import TYPE_CHECKING, NotRequired, TypedDict

from cadfeat.errors import CadfeatError

if TYPE_CHECKING:  # pragma: no cover
    from cadfeat.results import JsonDict

__all__ = ["EVENT_TOPIC", "CaseTimeout", "run_case", "warm_worker"]

#: The Dask event topic on which a worker announces the start of a case (key, pid, address, time).
EVENT_TOPIC = "cadfeat-campaign"


#: Seconds after a delivered ``CaseTimeout`` before it is raised again if the block still runs: an asynchronous
#: exception can land in a finaliser (``__del__``, a weakref callback, the garbage collector), where Python prints
#: "Exception ignored in …" and the study goes on; a study must not outrun its limit (and publish its folder) so.
REFIRE_S = 3.0


class CaseTimeout(BaseException):  # noqa: N818 - an interruption like KeyboardInterrupt, not an error class
    """Raised inside a case's thread when its wall-time limit has passed. Its creation (Python instantiates the
    class where the asynchronous exception is delivered) is noted per thread, for ``time_limit``'s re-firing."""

    delivered: dict[int, float] = {}  # thread id -> time.monotonic() of the latest delivery

    def __init__(self, *args: object) -> None:
        super().__init__(*args)
        CaseTimeout.delivered[threading.get_ident()] = time.monotonic()


def _raise_in(tid: int, exc: type[BaseException] | None) -> None:
    """Set (or, with None, withdraw) the asynchronous exception of thread ``tid``."""
    ctypes.pythonapi.PyThreadState_SetAsyncExc(ctypes.c_ulong(tid), ctypes.py_object(exc) if exc else None)


@contextlib.contextmanager
def time_limit(seconds: float, refire_s: float | None = None) -> Iterator[None]:
    """Raise ``CaseTimeout`` in this thread after ``seconds`` unless the block has finished by then; while the
    block still runs ``refire_s`` (default ``REFIRE_S``) after a delivery, raise it again: one swallowed by a
    finaliser does not let the study run on. (Not sooner: the unwinding — the staging folder's removal — must not
    be cut short by the next one.)"""
    tid = threading.get_ident()
    every = REFIRE_S if refire_s is None else refire_s
    lock = threading.Lock()
    state = {"done": False, "fired": False}
    timers: list[threading.Timer] = []
    CaseTimeout.delivered.pop(tid, None)

    def arm(delay: float) -> None:
        timer = threading.Timer(delay, fire)
        timer.daemon = True
        timers.append(timer)
        timer.start()

    def fire() -> None:
        with lock:
            if state["done"]:
                return
            last = CaseTimeout.delivered.get(tid)
            if not state["fired"] or (last is not None and time.monotonic() - last >= every):
                state["fired"] = True
                CaseTimeout.delivered.pop(tid, None)
                _raise_in(tid, CaseTimeout)
            arm(every)

    arm(seconds)
    try:
        yield
    finally:
        with lock:
            state["done"] = True
            for timer in timers:
                timer.cancel()
            if state["fired"]:  # a pending one not yet delivered (the block ended first): withdraw it
                _raise_in(tid, None)
            CaseTimeout.delivered.pop(tid, None)


def _announce(key: str | None) -> None:
    """Tell the campaign (Dask event) that this worker started ``key``: it counts running cases and knows which
    worker to restart if the case overruns its limit in C code."""
    try:
        from distributed import get_worker

        worker = get_worker()
    except (ImportError, ValueError):
        return
    worker.log_event(EVENT_TOPIC, {"key": key, "pid": os.getpid(), "host": socket.gethostname(),
                                   "worker": worker.address, "start": time.time()})


def _check_files(files: Mapping[str, str]) -> str | None:
    """None if every file exists here with the expected SHA-256, else the problem (one line)."""
    from cadfeat.campaign.plan import sha256_file  # lazy: would import pydantic at module load

    for path, digest in files.items():
        if not os.path.isfile(path):
            return f"{path} does not exist on worker host {socket.gethostname()} (the campaign's files must be " \
                   "at the same paths on every worker: a shared folder)"
        if sha256_file(path) != digest:
            return f"{path} on worker host {socket.gethostname()} differs from the file the campaign was planned " \
                   "with (same path, other bytes)"
    return None


def _daemonic() -> bool:
    return bool(multiprocessing.current_process().daemon)


class CasePayload(TypedDict):
    """What the runner sends a worker for one case (``run_case``)."""

    key: str
    study: JsonDict
    out_dir: str
    timeout_s: float
    files: dict[str, str]


class CaseOutcome(TypedDict):
    """A case's outcome (``run_case``; the runner's own for a lost or overdue case): its status ("done" | "failed"
    | "timeout"), the error (one line or None), the wall time (s; None when unknown), where it ran, and for a
    finished study the SHA-256 of its results.json; the runner adds the Dask worker."""

    status: str
    error: str | None
    wall_s: float | None
    host: NotRequired[str | None]
    pid: NotRequired[int | None]
    results_sha256: NotRequired[str]
    worker: NotRequired[str | None]


def run_case(payload: CasePayload) -> CaseOutcome:
    """Run one case (keys: ``key``, ``study``, ``out_dir``, ``timeout_s``, ``files``); returns its outcome:
    ``status`` ("done" | "failed" | "timeout"), ``error`` (one line or None), ``wall_s``, ``host``, ``pid``,
    and for a finished study ``results_sha256`` (of its results.json)."""
    _announce(payload.get("key"))
    t0 = time.perf_counter()
    host, pid = socket.gethostname(), os.getpid()
    problem = _check_files(payload.get("files", {}))
    if problem is None and _daemonic():
        problem = ("this Dask worker is a daemonic process, which may not start the CAD build processes a study "
                   "needs; start workers with DASK_DISTRIBUTED__WORKER__DAEMON=False (docs/guide/campaigns.md)")
    if problem is not None:
        return {"host": host, "pid": pid, "error": problem, "status": "failed", "wall_s": time.perf_counter() - t0}
    try:
        with time_limit(float(payload["timeout_s"])):
            _run(payload)
    except CaseTimeout:
        return {"host": host, "pid": pid,
                "error": f"exceeded the case time limit of {float(payload['timeout_s']):g} s and was stopped "
                         "(campaign.timeout_s or the case's timeout_s)",
                "status": "timeout", "wall_s": time.perf_counter() - t0}
    except Exception as exc:  # noqa: BLE001 - a failing study is an outcome, recorded with its error
        text = " ".join(str(exc).split()) or type(exc).__name__
        return {"host": host, "pid": pid, "error": text if _is_cadfeat(exc) else f"{type(exc).__name__}: {text}",
                "status": "failed", "wall_s": time.perf_counter() - t0}
    from cadfeat.campaign.plan import sha256_file  # lazy: would import pydantic at module load

    results = os.path.join(payload["out_dir"], "results.json")
    return {"host": host, "pid": pid, "error": None, "status": "done", "wall_s": time.perf_counter() - t0,
            "results_sha256": sha256_file(results)}


def _is_cadfeat(exc: BaseException) -> bool:
    return isinstance(exc, CadfeatError)


def _run(payload: CasePayload) -> None:
    """The study itself, as ``cadfeat run`` runs it (no progress display in a worker)."""
    from cadfeat.study import run_study  # lazy: its package loads it on first use

    run_study(dict(payload["study"]), payload["out_dir"], quiet=True, progress=False)


def warm_worker() -> int:
    """Import the study code and start the CAD worker server (CadQuery preloaded) in this worker, what its first
    case would otherwise pay; returns the worker's pid."""
    # lazy: would import scipy.optimize at module load
    from cadfeat.cad.parts import call_with_time_limit, start_workers
    from cadfeat.study import run  # noqa: F401

    start_workers()
    call_with_time_limit(os.getpid, (), "campaign worker warm-up", 300.0)  # waits until the server is up
    return os.getpid()
