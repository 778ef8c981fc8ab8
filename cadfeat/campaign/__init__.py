"""Campaigns: many studies (parts × cameras × paths × objective settings) as one run on Dask.

- ``spec``: the campaign file (TOML) and its pydantic v2 model, one-line errors;
- ``plan``: ``load_campaign`` — the cases, each a resolved and validated study dict with its input hash;
- ``task``: ``run_case`` — what a Dask worker runs for one case (``cadfeat.study.run_study``, time limit);
- ``store``: the campaign folder (records, resume, atomic writes); ``summary``: campaign.csv / .html / .json;
- ``runner``: ``run_campaign`` — LocalCluster or an existing scheduler, faults, Ctrl-C, progress.

``cadfeat campaign CAMPAIGN.toml`` on the command line; docs/guide/campaigns.md.
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING

if TYPE_CHECKING:  # pragma: no cover (the names ``__getattr__`` gives, for the type checker)
    from cadfeat.campaign.plan import load_campaign
    from cadfeat.campaign.runner import CampaignResult, run_campaign
    from cadfeat.campaign.spec import CampaignError

__all__ = ["CampaignError", "CampaignResult", "load_campaign", "run_campaign"]

_HOMES = {"CampaignError": "cadfeat.campaign.spec", "load_campaign": "cadfeat.campaign.plan",
          "CampaignResult": "cadfeat.campaign.runner", "run_campaign": "cadfeat.campaign.runner"}


def __getattr__(name: str) -> object:
    if name in _HOMES:
        return getattr(importlib.import_module(_HOMES[name]), name)
    raise AttributeError(f"module 'cadfeat.campaign' has no attribute {name!r}")
