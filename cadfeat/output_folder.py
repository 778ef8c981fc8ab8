"""Output folders cadfeat may write: ownership manifest, checks before any work, staged publishing.

cadfeat deletes or replaces only what it created itself (docs/design.md, "Trust rules"):

- every folder cadfeat publishes holds a manifest, ``.cadfeat-output.json``, listing the entries it wrote;
- a folder is *cadfeat's* when its manifest is valid and every entry in it is listed there: only such a
  folder is replaced as a whole (renamed aside, then deleted) by the next run into it;
- a non-empty folder that is not cadfeat's is refused before any work (``OutputFolderError``, one line with
  the ``--force`` / new-folder hint). With ``force`` cadfeat adds its files to the folder and leaves every
  other entry untouched; it still refuses when one of the names it writes (``OUTPUT_NAMES``) is already
  there and was not written by cadfeat — so ``--force`` never deletes the study file, the part or anything
  else cadfeat did not write;
- the destination must be writable: the staging folder is created beside it when the work starts (a read-only
  mount, a path under a regular file, ``/proc/x`` or an empty path fail there, before any work);
- staging folders are named ``.<name>.staging-<pid>-<hex>`` (and ``.<name>.old-<pid>-<hex>`` for the folder
  being replaced) and hold a manifest with the owner's pid and host; ``remove_stale_staging`` deletes those
  whose owner process is gone (a run killed with SIGKILL), and only those.
"""

from __future__ import annotations

import contextlib
import json
import os
import re
import secrets
import shutil
import socket
from collections.abc import Iterator, Sequence
from pathlib import Path
from typing import TYPE_CHECKING

from cadfeat._version import __version__
from cadfeat.errors import CadfeatError

if TYPE_CHECKING:  # pragma: no cover
    from cadfeat.results import JsonDict

__all__ = ["MANIFEST", "OUTPUT_NAMES", "REPORT_NAMES", "OutputFolderError", "check_output_folder", "is_cadfeat_folder",
           "pid_alive", "remove_stale_staging", "staged_output"]

MANIFEST = ".cadfeat-output.json"
"""The ownership manifest cadfeat writes into every folder it creates (and every staging folder)."""
OUTPUT_NAMES = ("original.step", "optimised.step", "optimised.stl", "move_only.step", "holes.csv", "results.json",
                "report.html", "img")
"""Entries cadfeat writes into an output folder (run, evaluate --out)."""
REPORT_NAMES = ("report.html", "img")
"""Entries ``cadfeat report`` writes."""
_STAGING = re.compile(r"^\..+\.(staging|old)-(\d+)-[0-9a-f]{8}$")


class OutputFolderError(CadfeatError):
    """The output folder cannot be used: not cadfeat's, not writable, or not a folder."""


def _manifest(folder: Path) -> JsonDict | None:
    """The folder's manifest, or None if it has no valid one (see ``_legacy_manifest`` for folders written
    before the manifest existed)."""
    try:
        data = json.loads((folder / MANIFEST).read_text(encoding="utf-8"))
    except FileNotFoundError:
        return _legacy_manifest(folder)
    except (OSError, ValueError, UnicodeDecodeError):
        return None
    if not isinstance(data, dict) or data.get("cadfeat_output") != 1 or not isinstance(data.get("files", []), list):
        return None
    return data


def _legacy_manifest(folder: Path) -> JsonDict | None:
    """An output folder of a cadfeat version without manifests: only names cadfeat writes (``OUTPUT_NAMES``),
    and a results.json that cadfeat wrote (it names ``cadfeat_version``). None for anything else."""
    if folder.is_symlink() or not folder.is_dir():
        return None
    try:
        names = {p.name for p in folder.iterdir()}
        results = json.loads((folder / "results.json").read_text(encoding="utf-8"))
    except (OSError, ValueError, UnicodeDecodeError):
        return None
    if not names <= set(OUTPUT_NAMES) or not isinstance(results, dict) or "cadfeat_version" not in results:
        return None
    return {"cadfeat_output": 1, "files": sorted(names), "legacy": True}


def _listed(folder: Path) -> set[str]:
    data = _manifest(folder)
    return set() if data is None else {str(f) for f in data.get("files", [])}


def _foreign(folder: Path) -> list[str]:
    """Entries of ``folder`` cadfeat did not write (not listed in its manifest), sorted."""
    listed = _listed(folder) if _manifest(folder) is not None else set()
    return sorted(p.name for p in folder.iterdir() if p.name != MANIFEST and p.name not in listed)


def is_cadfeat_folder(folder: str | os.PathLike[str]) -> bool:
    """Whether ``folder`` was created by cadfeat and holds only what cadfeat wrote (so it may be replaced)."""
    folder = Path(folder)
    return folder.is_dir() and _manifest(folder) is not None and not _foreign(folder)


def _absolute(final_dir: str | os.PathLike[str]) -> Path:
    text = os.fspath(final_dir)
    if not str(text).strip():
        raise OutputFolderError("output folder: an empty path is not allowed; give a folder, e.g. --out results/")
    if any(ord(c) < 32 for c in str(text)):
        raise OutputFolderError(f"output folder {text!r}: control characters (newline, tab, ...) are not allowed "
                                "in a folder name")
    return Path(os.path.abspath(text))


def _contains_cwd(folder: Path) -> bool:
    try:
        Path.cwd().resolve().relative_to(folder.resolve())
    except (ValueError, OSError):
        return False
    return True


def check_output_folder(final_dir: str | os.PathLike[str], force: bool = False,
                        names: Sequence[str] = OUTPUT_NAMES) -> Path:
    """Check, before any work, that cadfeat may write ``final_dir``; returns it as an absolute path.

    Raises ``OutputFolderError`` with one line when: the path is empty or has control characters; it, or a
    folder on the way to it, is an existing non-folder; it is a non-empty folder cadfeat did not create
    (unless ``force``); with ``force``, one of ``names`` exists there and was not written by cadfeat; the
    nearest existing folder on the way is not writable. (Whether the folder can really be created is proved
    by ``staged_output``, which creates the staging folder beside it first.)
    """
    final = _absolute(final_dir)
    shown = os.fspath(final_dir)
    if final.exists() and not final.is_dir():
        raise OutputFolderError(f"{shown}: output path exists and is not a folder; give a folder for the outputs")
    existing = final
    while not existing.exists():
        existing = existing.parent
    if not existing.is_dir():
        raise OutputFolderError(f"{shown}: {existing} is a file, so no folder can be created under it; give another "
                                "output folder")
    if final.is_dir():
        foreign = _foreign(final)
        if foreign and not force:
            listing = ", ".join(foreign[:5]) + (f" and {len(foreign) - 5} more" if len(foreign) > 5 else "")
            raise OutputFolderError(
                f"{shown}: output folder holds files cadfeat did not write ({listing}); nothing was done. Give a "
                "new folder (--out NEW_FOLDER), or --force to add cadfeat's files to it (other files are left "
                "untouched)")
        if force:
            listed = _listed(final)
            clash = sorted(n for n in names if (final / n).exists() and n not in listed)
            if clash:
                raise OutputFolderError(f"{shown}: {', '.join(clash)} already there and not written by cadfeat; "
                                        "even with --force cadfeat does not overwrite them: give a new folder")
    parent = final.parent if final.exists() else existing
    if not os.access(parent, os.W_OK | os.X_OK):
        raise OutputFolderError(f"{shown}: cannot write in {parent} (permission denied or read-only); give a "
                                "writable output folder")
    return final


def pid_alive(pid: int) -> bool:
    """Whether a process ``pid`` exists on this machine (one we may not signal counts as alive)."""
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    return True


def _owner_alive(pid: int, host: str) -> bool:
    if host != socket.gethostname():
        return True  # another machine's (shared filesystem): never ours to judge
    return pid_alive(pid)


def remove_stale_staging(parent: str | os.PathLike[str]) -> list[Path]:
    """Delete the staging / set-aside folders in ``parent`` left by cadfeat runs that were killed: named
    ``.<name>.staging-<pid>-<hex>`` or ``.<name>.old-<pid>-<hex>``, holding cadfeat's manifest with that pid
    and this host, whose process no longer exists; or so named, empty, with that pid dead (a run killed
    between creating the folder and writing its manifest: empty, or holding only a manifest file cut short).
    Returns the folders removed."""
    removed = []
    try:
        entries = list(Path(parent).iterdir())
    except OSError:
        return removed
    for path in entries:
        m = _STAGING.match(path.name)
        if not m or path.is_symlink() or not path.is_dir():
            continue
        data = _manifest(path)
        if data is None and not pid_alive(int(m.group(2))) and _remove_unfinished(path):
            removed.append(path)  # killed between creating the folder and finishing its manifest
            continue
        if data is None or int(data.get("pid", -1)) != int(m.group(2)):
            continue
        if _owner_alive(int(m.group(2)), str(data.get("host", ""))):
            continue
        shutil.rmtree(path, ignore_errors=True)
        removed.append(path)
    return removed


#: A manifest cut short by a kill is smaller than this (a whole one of a staging folder is ~300 bytes).
_UNFINISHED_MANIFEST_BYTES = 4096


def _remove_unfinished(path: Path) -> bool:
    """Remove a staging folder whose run was killed before its manifest was whole: empty, or holding only
    cadfeat's manifest file, invalid (cut short) and small; ``rmdir`` otherwise refuses (nothing anyone else
    wrote can be lost). True if it was removed."""
    try:
        entries = list(path.iterdir())
        if entries:
            if [e.name for e in entries] != [MANIFEST] or not entries[0].is_file() or entries[0].is_symlink():
                return False
            if entries[0].stat().st_size >= _UNFINISHED_MANIFEST_BYTES:
                return False
            entries[0].unlink()
        path.rmdir()
    except OSError:
        return False
    return True


def _sibling(final_dir: Path, role: str) -> Path:
    """An unused hidden path beside ``final_dir``: ``.<name>.<role>-<pid>-<random>``."""
    while True:
        path = final_dir.parent / f".{final_dir.name}.{role}-{os.getpid()}-{secrets.token_hex(4)}"
        if not path.exists():
            return path


def _write_manifest(folder: Path, files: Sequence[str], state: str) -> None:
    data = {"cadfeat_output": 1, "state": state, "files": sorted(files), "pid": os.getpid(),
            "host": socket.gethostname(), "cadfeat_version": __version__,
            "note": "written by cadfeat: it replaces this folder only while every entry is listed in 'files'"}
    (folder / MANIFEST).write_text(json.dumps(data, indent=1) + "\n", encoding="utf-8")


def _make_parents(folder: Path) -> list[Path]:
    """Create ``folder``'s missing ancestors; returns those created (outermost first)."""
    missing = []
    p = folder
    while not p.exists():
        missing.append(p)
        p = p.parent
    created = []
    for p in reversed(missing):
        p.mkdir()
        created.append(p)
    return created


@contextlib.contextmanager
def staged_output(final_dir: str | os.PathLike[str], force: bool = False, merge: bool = False,
                  names: Sequence[str] = OUTPUT_NAMES) -> Iterator[Path]:
    """Yield an empty staging folder beside ``final_dir``; publish it as ``final_dir`` only on success.

    ``check_output_folder`` runs first; then leftover staging folders of killed runs in the same parent are
    removed and the staging folder is created (this is where an unwritable destination fails, before any
    work). On normal exit: a missing ``final_dir`` becomes the staged folder; a folder cadfeat created is
    replaced (renamed aside, the staged folder renamed in, the old one deleted); an empty folder, a folder
    with other files (only with ``force``) or the current folder receives cadfeat's entries one by one,
    other entries untouched; ``merge``: always so (``cadfeat report`` adds report.html to a results folder).
    ``names``: the entries the block will write (a clash with an entry cadfeat did not write is refused).
    On any exception — ``KeyboardInterrupt`` and SIGTERM included — the staging
    folder (and any parent folder created for it) is deleted, ``final_dir`` is left exactly as it was and
    the exception propagates.
    """
    final = check_output_folder(final_dir, force, names)
    remove_stale_staging(final.parent if final.parent.exists() else final.parent.parent)
    created: list[Path] = []
    stage = _sibling(final, "staging")
    try:
        created = _make_parents(final.parent)
        stage.mkdir()  # (not mkdtemp: the published folder gets the usual permissions)
        _write_manifest(stage, [], "staging")
    except OSError as exc:
        shutil.rmtree(stage, ignore_errors=True)
        _remove_empty(created)
        raise OutputFolderError(f"{os.fspath(final_dir)}: cannot create the output folder here: "
                                f"{exc.strerror or exc}; give a writable output folder") from None
    try:
        yield stage
        try:
            _publish(stage, final, force, merge)
        except OSError as exc:  # e.g. the disk filled up, or another process took the name meanwhile
            raise OutputFolderError(f"{os.fspath(final_dir)}: could not move the outputs into place: {exc}") from exc
    except BaseException:
        shutil.rmtree(stage, ignore_errors=True)
        _remove_empty(created)
        raise


def _remove_empty(created: Sequence[Path]) -> None:
    for p in reversed(created):
        with contextlib.suppress(OSError):
            p.rmdir()


def _publish(stage: Path, final: Path, force: bool, merge: bool) -> None:
    files = sorted(p.name for p in stage.iterdir() if p.name != MANIFEST)
    _write_manifest(stage, files, "complete")
    if final.is_dir() and (merge or not is_cadfeat_folder(final) or _contains_cwd(final)):
        check_output_folder(final, force or merge or not _foreign(final), files)  # (changed since the start?)
        _merge(stage, final, files)
        return
    old = None
    try:
        if final.exists():
            old = _sibling(final, "old")
            os.rename(final, old)
        os.rename(stage, final)
    except BaseException:
        if old is not None and not final.exists():
            os.rename(old, final)
            old = None
        raise
    finally:
        if old is not None:
            shutil.rmtree(old, ignore_errors=True)


def _merge(stage: Path, final: Path, files: Sequence[str]) -> None:
    """Move the staged entries into an existing folder: replace only entries cadfeat wrote before (listed
    in the folder's manifest; ``check_output_folder`` refused any other clash), leave every other entry as it
    is. The manifest then lists cadfeat's entries of both."""
    previous = {n for n in _listed(final) if (final / n).exists()}
    for name in files:
        target = final / name
        if target.exists() or target.is_symlink():
            _remove(target)
        os.rename(stage / name, target)
    _write_manifest(final, sorted(previous | set(files)), "complete")
    shutil.rmtree(stage, ignore_errors=True)


def _remove(path: Path) -> None:
    if path.is_dir() and not path.is_symlink():
        shutil.rmtree(path)
    elif path.exists() or path.is_symlink():
        path.unlink()
