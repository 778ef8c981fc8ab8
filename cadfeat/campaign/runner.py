"""Run a campaign on Dask: ``run_campaign(path, out, scheduler=..., workers=...)``.

1. ``load_campaign`` validates the campaign and every case's study (nothing runs before that);
2. the output folder is claimed (``CampaignStore.open``) and finished cases (same input hash, results.json
   intact) are skipped;
3. the other cases are submitted to Dask as plain study dicts (``task.run_case``): a ``LocalCluster`` of
   ``workers`` processes with one thread each (so one study, hence one CAD build, per worker at a time), or
   the cluster at ``scheduler`` (``tcp://host:8786``);
4. each outcome is recorded as it arrives (``records/<case>.json``) and ``campaign.csv`` rewritten; at the end
   ``campaign.csv``, ``campaign.html`` and ``campaign.json`` (``cadfeat.campaign.summary``).

Faults: a study that raises is a ``failed`` case, one that overruns its limit a ``timeout`` case (stopped in
the worker, or — stuck in C code for ``timeout_s + grace`` — by restarting its worker); a worker process that
dies has its case re-run on another worker up to ``[campaign] retries`` times (Dask's ``allowed-failures``),
then the case is ``failed``. Ctrl-C / SIGTERM: pending cases are cancelled, the local cluster is shut down,
staging folders of the stopped studies are removed (their owner process is gone: the study layer's rule),
the summary is written with those cases ``interrupted``, and the interrupt propagates; every finished case
folder is untouched.
"""

from __future__ import annotations

import contextlib
import json
import logging
import os
import signal
import socket
import threading
import time
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

from cadfeat.campaign.plan import Campaign, Case, load_campaign
from cadfeat.campaign.store import CampaignStore
from cadfeat.campaign.summary import write_csv, write_summary
from cadfeat.campaign.task import EVENT_TOPIC, run_case
from cadfeat.output_folder import pid_alive

if TYPE_CHECKING:  # pragma: no cover
    from types import FrameType

    from distributed import Client, Future
    from rich.progress import Progress

    from cadfeat.campaign.task import CaseOutcome, CasePayload
    from cadfeat.results import JsonDict

__all__ = ["EXPORTS_DIR", "CampaignResult", "local_cluster", "run_campaign"]

EXPORTS_DIR = Path("exports")
#: Extra time (s) a case gets past its limit before its worker is restarted (the in-worker stop comes first).
GRACE_S = 15.0
POLL_S = 0.2


@dataclass(frozen=True)
class CampaignResult:
    """Where the campaign wrote, its per-case records (case order), and what this run did."""

    out_dir: Path
    records: list[JsonDict]
    ran: int
    skipped: int
    wall_s: float

    def count(self, status: str) -> int:
        return sum(1 for r in self.records if r.get("status") == status)

    def summary(self) -> str:
        counts = {s: self.count(s) for s in ("done", "failed", "timeout", "interrupted")}
        text = ", ".join(f"{n} {s}" for s, n in counts.items() if n)
        return (f"campaign: {len(self.records)} case(s): {text or 'none'} ({self.ran} run now, {self.skipped} "
                f"already finished) in {self.wall_s:.1f} s\n  summary: {self.out_dir / 'campaign.csv'}\n"
                f"           {self.out_dir / 'campaign.html'}")


@contextlib.contextmanager
def local_cluster(workers: int | None, retries: int = 1) -> Iterator[Client]:
    """A ``LocalCluster`` client: ``workers`` processes (default: the CPU count), one thread each, non-daemonic
    (a study starts CAD build processes), no dashboard, the cores shared out among the workers' render threads
    (``LP_NUM_THREADS``, Mesa llvmpipe); a case is re-run ``retries`` times if its worker dies."""
    import dask.config
    from distributed import Client, LocalCluster

    n = workers or os.cpu_count() or 1
    environ = {**dask.config.get("distributed.nanny.pre-spawn-environ", {}),
               "LP_NUM_THREADS": max(1, (os.cpu_count() or 1) // n)}  # the report's software renderer: the
    # workers already fill the cores, more render threads per worker would only compete
    # (the settings hold for the cluster's whole life: a nanny reads them again when it restarts a dead worker)
    with dask.config.set({"distributed.worker.daemon": False, "distributed.scheduler.allowed-failures": retries,
                          "distributed.nanny.pre-spawn-environ": environ}):
        cluster = LocalCluster(n_workers=n, threads_per_worker=1, processes=True, dashboard_address=None,
                               silence_logs=logging.ERROR)
        client = Client(cluster)
        try:
            yield client
        finally:
            with contextlib.suppress(Exception):
                client.close()
            with contextlib.suppress(Exception):
                cluster.close()


@contextlib.contextmanager
def _client(scheduler: str | None, workers: int | None, retries: int, client: Client | None) -> Iterator[Client]:
    if client is not None:
        yield client
    elif scheduler:
        from distributed import Client

        with Client(scheduler, timeout="30s") as c:
            yield c
    else:
        with local_cluster(workers, retries) as c:
            yield c


def run_campaign(path_or_campaign: str | os.PathLike[str] | Campaign, out_dir: str | os.PathLike[str] | None = None,
                 *, scheduler: str | None = None, workers: int | None = None, client: Client | None = None,
                 quiet: bool = False, progress: bool = True) -> CampaignResult:
    """Run every unfinished case of a campaign (see the module docstring); returns the records of all cases.

    ``scheduler``: address of a running Dask scheduler; else a ``LocalCluster`` of ``workers`` processes (or
    ``client``, an existing ``distributed.Client``). Raises ``CampaignError`` on bad input (nothing run).
    """
    t0 = time.perf_counter()
    campaign = path_or_campaign if isinstance(path_or_campaign, Campaign) else load_campaign(path_or_campaign)
    store = CampaignStore.open(out_dir if out_dir is not None else EXPORTS_DIR / campaign.name, campaign)
    store.remove_stale_staging()
    todo = [c for c in campaign.cases if not store.finished(c)]
    skipped = len(campaign.cases) - len(todo)
    outcomes: dict[str, JsonDict] = {}
    try:
        if todo:
            with _client(scheduler, workers, campaign.retries, client) as c, \
                    _Display(len(todo), skipped, enabled=progress and not quiet) as display:
                execution = _Execution(c, store, todo, display, outcomes)
                try:
                    execution.run()
                except BaseException:
                    if scheduler is None and client is None:  # our own LocalCluster: stop now, not after the study
                        execution.kill_busy_workers()
                    raise
    except BaseException:
        _cleanup_after_stop(store)
        for case in todo:
            if case.name not in outcomes:
                outcomes[case.name] = store.save(case, {"status": "interrupted", "error": "campaign interrupted"})
        with contextlib.suppress(Exception):
            write_summary(store, campaign)
        raise
    _cleanup_after_stop(store)
    records = write_summary(store, campaign)
    return CampaignResult(store.root, records, len(todo), skipped, time.perf_counter() - t0)


def _cleanup_after_stop(store: CampaignStore, wait_s: float = 20.0) -> None:
    """Remove the staging folders of stopped studies once their owner processes (workers) are gone."""
    deadline = time.monotonic() + wait_s
    for stage in store.staging_left():
        try:
            pid = int(json.loads((stage / ".cadfeat-output.json").read_text())["pid"])
        except (OSError, ValueError, KeyError, TypeError):
            continue
        while time.monotonic() < deadline and pid_alive(pid):
            time.sleep(0.1)
    store.remove_stale_staging()




class _Stop:
    """A SIGINT / SIGTERM noted by ``_deferred_signals``, raised by ``check`` from the campaign's own loop."""

    def __init__(self) -> None:
        self.signum: int | None = None
        self.previous: dict[int, object] = {}

    def check(self) -> None:
        if self.signum is None:
            return
        handler = self.previous.get(self.signum)
        if callable(handler):
            handler(self.signum, None)  # Ctrl-C: KeyboardInterrupt; SIGTERM under the CLI: Terminated
        raise KeyboardInterrupt


@contextlib.contextmanager
def _deferred_signals() -> Iterator[_Stop]:
    """Within the block, SIGINT and SIGTERM only set a flag that the loop checks (``_Stop.check``): raised
    directly, the interrupt can land in a callback of Dask's own (a garbage-collection hook) and be swallowed
    there ("Exception ignored in ..."), and the campaign would run on."""
    stop = _Stop()
    if threading.current_thread() is not threading.main_thread():
        yield stop
        return

    def note(signum: int, frame: FrameType | None) -> None:
        stop.signum = signum

    for sig in (signal.SIGINT, signal.SIGTERM):
        stop.previous[sig] = signal.signal(sig, note)
    try:
        yield stop
    finally:
        for sig, handler in stop.previous.items():
            signal.signal(sig, handler)


class _Execution:
    """Submit the cases, follow them, enforce the hard time limit, record outcomes as they arrive."""

    def __init__(self, client: Client, store: CampaignStore, todo: list[Case], display: _Display,
                 outcomes: dict[str, JsonDict]) -> None:
        self.client, self.store, self.display, self.outcomes = client, store, display, outcomes
        self.started: dict[str, JsonDict] = {}
        self.lock = threading.Lock()
        self.cases = {self._key(c): c for c in todo}
        self.outcomes_keys: set[str] = set()

    def _key(self, case: Case) -> str:
        return f"cadfeat-case-{case.name}-{case.input_hash[:8]}-{os.getpid()}-{time.monotonic_ns()}"

    def _on_event(self, event: object) -> None:
        msg = event[1] if isinstance(event, tuple) else event
        if isinstance(msg, dict) and msg.get("key") in self.cases:
            with self.lock:
                self.started[msg["key"]] = {**msg, "seen": time.monotonic()}

    def run(self) -> None:
        with contextlib.suppress(Exception):
            self.client.subscribe_topic(EVENT_TOPIC, self._on_event)
        futures = {}
        for key, case in self.cases.items():
            payload: CasePayload = {"key": key, "study": case.study, "out_dir": str(self.store.case_dir(case)),
                                    "timeout_s": case.timeout_s, "files": case.files}
            futures[key] = self.client.submit(run_case, payload, key=key, pure=False)
        pending = dict(futures)
        try:
            with _deferred_signals() as stop:
                while pending:
                    stop.check()
                    for key, fut in list(pending.items()):
                        outcome = self._outcome(key, fut)
                        if outcome is None:
                            continue
                        del pending[key]
                        self.outcomes_keys.add(key)
                        case = self.cases[key]
                        self.outcomes[case.name] = self.store.save(case, outcome)
                        self.display.finished(outcome["status"])
                        with contextlib.suppress(Exception):
                            write_csv(self.store, self.store.campaign)
                    with self.lock:
                        running = sum(1 for k in pending if k in self.started)
                    self.display.running(running)
                    time.sleep(POLL_S)
                stop.check()
        finally:
            if pending:
                self.client.cancel(list(pending.values()))
            with contextlib.suppress(Exception):
                self.client.unsubscribe_topic(EVENT_TOPIC)

    def kill_busy_workers(self) -> None:
        """SIGKILL the local worker processes still running a case (Ctrl-C on a LocalCluster): a graceful close
        would wait for their studies to finish. Their staging folders are removed afterwards (owner gone)."""
        with self.lock:
            busy = [s for k, s in self.started.items() if k not in self.outcomes_keys]
        for start in busy:
            if start.get("host") == socket.gethostname():
                with contextlib.suppress(OSError, TypeError, ValueError):
                    os.kill(int(start["pid"]), signal.SIGKILL)

    def _outcome(self, key: str, fut: Future) -> CaseOutcome | None:
        """The outcome of a finished future; None while it runs (after enforcing the hard time limit)."""
        if fut.status == "finished":
            out: CaseOutcome = {**fut.result()}
            out["worker"] = self.started.get(key, {}).get("worker")
            return out
        if fut.status in ("error", "cancelled"):
            exc = fut.exception() if fut.status == "error" else None
            name = type(exc).__name__ if exc is not None else fut.status
            text = " ".join(str(exc).split()) if exc is not None else ""
            if name == "KilledWorker":
                text = (f"its worker process died on every attempt (out of memory, a crash in the CAD kernel, or "
                        f"killed); {text}")
            return {"status": "failed", "error": f"{name}: {text}".strip(": "), "wall_s": None}
        with self.lock:
            start = self.started.get(key)
        case = self.cases[key]
        if start is not None and time.monotonic() - start["seen"] > case.timeout_s + GRACE_S:
            self.client.cancel([fut])
            with contextlib.suppress(Exception):
                self.client.restart_workers([start["worker"]], raise_for_error=False)
            return {"status": "timeout", "wall_s": time.monotonic() - start["seen"], "host": None,
                    "pid": start.get("pid"),
                    "error": f"exceeded the case time limit of {case.timeout_s:g} s by more than {GRACE_S:g} s "
                             "without stopping (busy in C code); its worker was restarted"}
        return None


class _Display:
    """Console progress (rich): cases done / failed / running, elapsed time and ETA."""

    def __init__(self, total: int, skipped: int, enabled: bool) -> None:
        self.total, self.skipped, self.enabled = total, skipped, enabled
        self.done = self.failed = 0
        self.progress: Progress | None = None

    def __enter__(self) -> _Display:
        if self.enabled:
            from rich.progress import (
                BarColumn,
                MofNCompleteColumn,
                Progress,
                TextColumn,
                TimeElapsedColumn,
                TimeRemainingColumn,
            )

            self.progress = Progress(TextColumn("campaign"), BarColumn(), MofNCompleteColumn(),
                                     TextColumn("done {task.fields[done]} · failed {task.fields[failed]} · "
                                                "running {task.fields[running]} · skipped {task.fields[skipped]}"),
                                     TimeElapsedColumn(), TextColumn("ETA"), TimeRemainingColumn())
            self.progress.start()
            self.task = self.progress.add_task("cases", total=self.total, done=0, failed=0, running=0,
                                               skipped=self.skipped)
        return self

    def __exit__(self, *exc: object) -> None:
        if self.progress is not None:
            self.progress.stop()

    def finished(self, status: str) -> None:
        if status == "done":
            self.done += 1
        else:
            self.failed += 1
        if self.progress is not None:
            self.progress.update(self.task, advance=1, done=self.done, failed=self.failed)

    def running(self, n: int) -> None:
        if self.progress is not None:
            self.progress.update(self.task, running=n)
