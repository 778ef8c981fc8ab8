"""The sandbox of part-script code and CAD work: captured output, a time limit, worker processes.

A part script is Python run with the user's rights and a CAD rebuild may hang (docs/design.md, "Known pitfalls"):
``contained`` runs script code with its output captured and ``sys.exit`` refused; ``run_worker`` runs a
function in a worker process (forkserver with CadQuery preloaded) killed after a time limit;
``call_with_time_limit`` is the public form. The limit is always passed explicitly (``load_part(path,
time_limit_s)``, ``call_with_time_limit(..., timeout_s)``, ``setup_study(config, time_limit_s=...)``; None: in
this process, no limit): there is no process-wide setting. This module imports no numpy and no CadQuery
(``cadfeat --help`` stays fast).
"""

from __future__ import annotations

import contextlib
import io
import math
import multiprocessing
import os
import signal
import sys
import threading
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import TYPE_CHECKING, Generic, TypeVar, cast

if TYPE_CHECKING:  # pragma: no cover
    from multiprocessing.connection import Connection
    from multiprocessing.context import BaseContext
    from types import FrameType

from cadfeat.errors import CadfeatError

__all__ = ["DEFAULT_BUILD_TIMEOUT_S", "TIME_LIMIT_HINT", "BackgroundCall", "PartBuildError", "call_with_time_limit",
           "check_time_limit", "contained", "run_worker", "start_workers", "worker_setup"]

DEFAULT_BUILD_TIMEOUT_S = 60.0
"""Time limit (s) of one part-script import or build in the ``cadfeat`` commands (``[study] build_timeout_s``
changes it for a study, ``--build-timeout`` for ``cadfeat parts`` / ``render``)."""
TIME_LIMIT_HINT = "if it needs longer, raise [study] build_timeout_s (cadfeat parts / render: --build-timeout S)"


class PartBuildError(CadfeatError):
    """A part build raised, returned no solid, or exceeded its time limit."""


def check_time_limit(seconds: float | None) -> float | None:
    """``seconds`` if it is a time limit (finite, > 0) or None (no limit: in this process); else one
    ``CadfeatError`` line."""
    if seconds is not None and not (math.isfinite(seconds) and seconds > 0):
        raise CadfeatError(f"build time limit: {seconds!r} s is not allowed; allowed: a number of seconds > 0")
    return seconds


class _Sink(io.TextIOBase):
    """A text stream keeping the first ``keep`` characters written to it and counting the rest."""

    def __init__(self, keep: int = 4000) -> None:
        self.keep, self.text, self.n_chars = keep, "", 0

    def writable(self) -> bool:
        return True

    def write(self, s: str) -> int:
        if len(self.text) < self.keep:
            self.text += s[:self.keep - len(self.text)]
        self.n_chars += len(s)
        return len(s)


@contextlib.contextmanager
def contained(path: Path, what: str, echo: bool = False) -> Iterator[None]:
    """Run part-script code: its ``print`` output is captured (bounded: a flood cannot fill the terminal or
    memory; with ``echo``, up to 20 lines are shown on stderr afterwards), ``sys.exit`` becomes a
    ``CadfeatError``, and Ctrl-C during the block is reported as an interrupt even if the module being
    imported turned it into another exception (e.g. an ``ImportError`` from an extension module)."""
    sink = _Sink()
    interrupted = []
    main = threading.current_thread() is threading.main_thread()
    previous = signal.getsignal(signal.SIGINT) if main else None

    def on_sigint(signum: int, frame: FrameType | None) -> None:
        interrupted.append(signum)
        raise KeyboardInterrupt

    if main and previous is signal.default_int_handler:
        signal.signal(signal.SIGINT, on_sigint)
    try:
        with contextlib.redirect_stdout(sink), contextlib.redirect_stderr(sink):
            yield
    except SystemExit as exc:
        raise CadfeatError(f"{path}: {what} called sys.exit({exc.code!r}); a part script must not exit "
                           "(raise an exception to report a problem)") from None
    except KeyboardInterrupt:
        raise
    except BaseException:
        if interrupted:
            raise KeyboardInterrupt from None
        raise
    finally:
        if main and previous is signal.default_int_handler:
            signal.signal(signal.SIGINT, previous)
        if echo and sink.n_chars:
            lines = sink.text.splitlines()[:20]
            shown = sum(len(line) + 1 for line in lines)
            more = f"\n    ... ({sink.n_chars - shown} more characters not shown)" if sink.n_chars > shown else ""
            print(f"{path.name} printed while {what}:\n" + "\n".join(f"    {line}" for line in lines) + more,
                  file=sys.stderr)


# ------------------------------------------------------------------------------------ worker processes
def worker_setup() -> None:
    """In a worker: die with the forkserver (so with cadfeat), send C-level output to /dev/null, and ignore SIGINT:
    Ctrl-C in a terminal reaches the whole process group, and what it means is cadfeat's to decide (a run keeps
    its best design and finishes its rebuild, ``study.interrupts``); cadfeat stops its workers itself."""
    with contextlib.suppress(ValueError, OSError):
        signal.signal(signal.SIGINT, signal.SIG_IGN)
    with contextlib.suppress(Exception):  # Linux: SIGKILL when the parent (the forkserver) exits
        import ctypes

        ctypes.CDLL(None, use_errno=True).prctl(1, int(signal.SIGKILL))  # PR_SET_PDEATHSIG
    with contextlib.suppress(OSError):
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, 1)
        os.dup2(devnull, 2)
        os.close(devnull)


_CONTEXT: BaseContext | None = None


def _context() -> BaseContext:
    """The multiprocessing context: forkserver (cadquery preloaded) where available, spawn otherwise."""
    global _CONTEXT
    if _CONTEXT is None:
        if "forkserver" in multiprocessing.get_all_start_methods():
            _CONTEXT = multiprocessing.get_context("forkserver")
            _CONTEXT.set_forkserver_preload(["cadquery", "cadfeat.cad.parts", "cadfeat.cad.sandbox"])
        else:  # pragma: no cover - Windows / macOS defaults
            _CONTEXT = multiprocessing.get_context("spawn")
    return _CONTEXT


def start_workers() -> None:
    """Start the worker server now (it imports CadQuery meanwhile), so the first time-limited import or build
    does not wait for it; nothing to do with the spawn method."""
    if _context().get_start_method() == "forkserver":
        from multiprocessing import forkserver  # lazy: keeps `cadfeat --help` fast

        forkserver.ensure_running()


class _Worker:
    """``target(*args, conn)`` in a worker process (the forkserver; a daemon: it dies with cadfeat), started now;
    its one ``(status, payload)`` reply read later (``reply``); ``stop`` kills it if it still runs."""

    def __init__(self, target: Callable[..., None], args: tuple[object, ...]) -> None:
        ctx = _context()
        self._receive, send = ctx.Pipe(duplex=False)
        self.proc = ctx.Process(target=target, args=(*args, send), daemon=True)
        self.proc.start()
        send.close()

    def reply(self, timeout_s: float, what: str) -> tuple[str, object] | None:
        """The worker's reply, None when none came within ``timeout_s``; ``PartBuildError`` if it died."""
        if not self._receive.poll(timeout_s):
            return None
        try:
            return self._receive.recv()
        except EOFError:
            self.proc.join(5.0)
            raise PartBuildError(f"{what}: worker died (exit code {self.proc.exitcode}): out of memory, or a crash "
                                 "in the CAD kernel?") from None

    def stop(self) -> None:
        """Kill the worker (if it still runs) and free the pipe."""
        self._receive.close()
        if self.proc.is_alive():
            self.proc.kill()
        self.proc.join()


def run_worker(target: Callable[..., None], args: tuple[object, ...], timeout_s: float, what: str
               ) -> tuple[str, object]:
    """``target(*args, conn)`` in a worker process: its ``(status, payload)`` reply, or ``PartBuildError`` when
    no reply comes within ``timeout_s`` (the worker is killed) or the worker dies."""
    worker = _Worker(target, args)
    try:
        reply = worker.reply(timeout_s, what)
    finally:
        worker.stop()
    if reply is None:
        raise PartBuildError(f"{what} exceeded the time limit of {timeout_s:g} s and was stopped; {TIME_LIMIT_HINT}")
    return reply


def _payload(reply: tuple[str, object], what: str) -> object:
    """The payload of ``_call_worker``'s ``("ok", payload)``; its ``("error", message)`` as ``PartBuildError``."""
    status, payload = reply
    if status != "ok":
        raise PartBuildError(f"{what}: {payload}")
    return payload


def _call_worker(func: Callable[..., object], args: tuple[object, ...], conn: Connection) -> None:
    """Worker process: send ('ok', func(*args)) or ('error', message)."""
    worker_setup()
    try:
        conn.send(("ok", func(*args)))
    except BaseException as exc:  # noqa: BLE001 - everything goes back to the parent as a message
        conn.send(("error", f"{exc}" if isinstance(exc, CadfeatError) else f"{type(exc).__name__}: {exc}"))
    finally:
        conn.close()


R = TypeVar("R")


def call_with_time_limit(func: Callable[..., R], args: tuple[object, ...], what: str, timeout_s: float | None) -> R:
    """``func(*args)`` in a worker process within ``timeout_s`` (None: in this process). ``func`` must be
    importable and ``args`` and the result picklable (CadQuery shapes are). A timeout, a dead worker or an
    exception raises ``PartBuildError`` starting with ``what``. Used for the CAD work that is not a part
    script's build, e.g. re-drilling a STEP part's holes."""
    if check_time_limit(timeout_s) is None:
        return func(*args)
    return cast(R, _payload(run_worker(_call_worker, (func, args), timeout_s, what), what))  # (func's result)


class BackgroundCall(Generic[R]):
    """``func(*args)`` in a worker process started now, its result collected later (``result``) or the worker
    killed (``cancel``): work that does not depend on what this process does meanwhile runs on another core
    (the study's closed-loop check tracks the original design while the optimiser runs). ``func`` must be
    importable and ``args`` and the result picklable. The worker is a daemon: it dies with cadfeat."""

    def __init__(self, func: Callable[..., R], args: tuple[object, ...], what: str) -> None:
        self.what = what
        self._worker = _Worker(_call_worker, (func, args))

    def result(self, timeout_s: float) -> R:
        """``func(*args)``; ``PartBuildError`` (starting with ``what``) when the worker raised, died or did not
        answer within ``timeout_s``. The worker is gone afterwards."""
        try:
            reply = self._worker.reply(timeout_s, self.what)
        finally:
            self.cancel()
        if reply is None:
            raise PartBuildError(f"{self.what} gave no result within {timeout_s:g} s")
        return cast(R, _payload(reply, self.what))  # (what ``func`` returned, pickled back)

    def cancel(self) -> None:
        """Kill the worker (if it still runs) and free the pipe."""
        self._worker.stop()
