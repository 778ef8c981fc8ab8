"""A campaign's output folder: ownership marker, per-case records, resume, atomic summary files.

Layout of ``<out>/`` (default ``exports/<campaign name>/``)::

    .cadfeat-campaign.json   marker: this folder is a campaign's (name, campaign file)
    cases/<case>/            each case's study outputs, written and published by ``run_study`` (its own
                             ownership manifest and staging: the study layer's rules for output folders)
    records/<case>.json      the case's outcome: status, error, input hash, results.json SHA-256, times, host
    campaign.csv, campaign.html, campaign.json   the summary

cadfeat never writes into a non-empty folder without the marker (one-line error before any work), and replaces
only files it wrote: records and summaries are written to a temporary file beside them and renamed into place,
so an interrupted campaign leaves either the old or the new file, never half of one.

A case counts as finished (skipped on the next run) when its record says ``done`` with the same input hash and
``cases/<case>/results.json`` still has the SHA-256 recorded.
"""

from __future__ import annotations

import json
import os
import secrets
import time
from pathlib import Path
from typing import TYPE_CHECKING

from cadfeat.campaign.plan import Campaign, Case, sha256_file
from cadfeat.campaign.spec import CampaignError

if TYPE_CHECKING:  # pragma: no cover
    from cadfeat.campaign.task import CaseOutcome
    from cadfeat.results import JsonDict

__all__ = ["MARKER", "CampaignStore", "atomic_write"]

MARKER = ".cadfeat-campaign.json"


def atomic_write(path: Path, text: str | bytes) -> None:
    """Write ``path`` via a temporary sibling and ``os.replace`` (never half-written)."""
    tmp = path.with_name(f".{path.name}.tmp-{os.getpid()}-{secrets.token_hex(4)}")
    try:
        if isinstance(text, bytes):
            tmp.write_bytes(text)
        else:
            tmp.write_text(text, encoding="utf-8")
        os.replace(tmp, path)
    finally:
        if tmp.exists():
            tmp.unlink()


class CampaignStore:
    """The output folder of one campaign (``open`` checks and claims it)."""

    def __init__(self, root: Path, campaign: Campaign) -> None:
        self.root = root
        self.campaign = campaign
        self.cases_dir = root / "cases"
        self.records_dir = root / "records"

    @classmethod
    def open(cls, out: str | os.PathLike[str], campaign: Campaign) -> CampaignStore:
        """Check ``out`` (missing, empty, or a campaign folder of the same name) and create its layout."""
        root = Path(os.path.abspath(os.fspath(out)))
        shown = os.fspath(out)
        if root.exists() and not root.is_dir():
            raise CampaignError(f"{shown}: output path exists and is not a folder; give a folder (--out DIR)")
        if root.is_dir() and any(root.iterdir()):
            marker = _read_json(root / MARKER)
            if marker is None or marker.get("cadfeat_campaign") != 1:
                raise CampaignError(f"{shown}: folder holds files a cadfeat campaign did not write; nothing was "
                                    "done. Give a new folder (--out NEW_FOLDER)")
            if marker.get("name") != campaign.name:
                raise CampaignError(f"{shown}: folder belongs to campaign {marker.get('name')!r}, not "
                                    f"{campaign.name!r}; give another folder (--out DIR)")
        try:
            root.mkdir(parents=True, exist_ok=True)
            for d in ("cases", "records"):
                (root / d).mkdir(exist_ok=True)
            atomic_write(root / MARKER, json.dumps({"cadfeat_campaign": 1, "name": campaign.name,
                                                    "file": str(campaign.file)}, indent=1) + "\n")
        except OSError as exc:
            raise CampaignError(f"{shown}: cannot write the campaign folder here: {exc.strerror or exc}; give a "
                                "writable folder (--out DIR)") from None
        return cls(root, campaign)

    def case_dir(self, case: Case) -> Path:
        return self.cases_dir / case.name

    def record_path(self, case: Case) -> Path:
        return self.records_dir / f"{case.name}.json"

    def record(self, case: Case) -> JsonDict | None:
        return _read_json(self.record_path(case))

    def finished(self, case: Case) -> bool:
        """Whether ``case`` has a complete result for its current inputs (see the module docstring)."""
        rec = self.record(case)
        if not rec or rec.get("status") != "done" or rec.get("input_hash") != case.input_hash:
            return False
        results = self.case_dir(case) / "results.json"
        return results.is_file() and sha256_file(results) == rec.get("results_sha256")

    def save(self, case: Case, outcome: CaseOutcome) -> JsonDict:
        """Record a case's outcome (atomically); returns the record."""
        rec = {"case": case.name, "index": case.index, "values": case.values, "input_hash": case.input_hash,
               "recorded": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime()), **dict(outcome)}
        atomic_write(self.record_path(case), json.dumps(rec, indent=1, sort_keys=True, default=str) + "\n")
        return rec

    def results(self, case: Case) -> JsonDict | None:
        return _read_json(self.case_dir(case) / "results.json")

    def remove_stale_staging(self) -> list[Path]:
        """Staging folders of studies whose worker was killed (the study layer's own rule: owner pid gone)."""
        from cadfeat.output_folder import remove_stale_staging  # lazy: its package loads it on first use

        return remove_stale_staging(self.cases_dir)

    def staging_left(self) -> list[Path]:
        return sorted(p for p in self.cases_dir.iterdir() if p.name.startswith(".") and ".staging-" in p.name)


def _read_json(path: Path) -> JsonDict | None:
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError, UnicodeDecodeError):
        return None
    return data if isinstance(data, dict) else None
