"""Hashing a study's inputs: the bytes of a file (``sha256_file``) and plain data as canonical JSON
(``canonical_json``). A campaign's input hash (``campaign.plan``) and the set-up cache's key
(``study.setup_cache``) are made of these, so the two agree on what "the same inputs" means. Standard library only.
"""

from __future__ import annotations

import hashlib
import json
import os
from typing import Any

__all__ = ["canonical_json", "sha256_file"]


def sha256_file(path: str | os.PathLike[str]) -> str:
    """SHA-256 of a file's bytes (hex)."""
    h = hashlib.sha256()
    with open(path, "rb") as fh:
        for block in iter(lambda: fh.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


def canonical_json(data: Any) -> bytes:
    """``data`` as canonical JSON bytes (sorted keys, no blanks, not ASCII-escaped; paths and the like as their
    ``str``): equal data, equal bytes."""
    return json.dumps(data, sort_keys=True, separators=(",", ":"), ensure_ascii=False, default=str).encode()
