"""Error types. Every error caused by user input derives from ``CadfeatError`` and names the file,
the key and what is allowed; the CLI prints these without a traceback."""

from __future__ import annotations


class CadfeatError(ValueError):
    """Bad user input (study file, part script, camera, trajectory...): a clear one-line message."""
