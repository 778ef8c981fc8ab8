"""Error types. Every error caused by user input derives from ``CadfeatError`` and names the file,
the key and what is allowed; the CLI prints these without a traceback."""

from __future__ import annotations


class CadfeatError(ValueError):
    """Bad user input (study file, part script, camera, trajectory...): a clear one-line message."""


class Terminated(BaseException):  # noqa: N818 - named after the signal, like KeyboardInterrupt
    """Raised in the main thread by cadfeat's SIGTERM handler: unwinds like Ctrl-C (staging folders and worker
    processes are cleaned up on the way), but is never taken for a request to keep the best design so far;
    the CLI exits with status 143 (128 + SIGTERM)."""


class CadfeatWarning(UserWarning):
    """Something cadfeat worked around and the user should know (the CLI prints it as one ``warning:`` line)."""
