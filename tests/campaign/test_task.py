"""The case time limit of a campaign worker (``cadfeat.campaign.task.time_limit``): asynchronous ``CaseTimeout``.

Reference: the wall clock. A block that catches the first ``CaseTimeout`` — as a finaliser does, where Python
prints "Exception ignored in …" and goes on — is still stopped; a block that ends in time is not interrupted later.
"""

from __future__ import annotations

import time

import pytest

from cadfeat.campaign.task import CaseTimeout, time_limit


def _busy(seconds: float) -> None:
    end = time.monotonic() + seconds
    while time.monotonic() < end:
        sum(range(100))  # Python bytecode: where an asynchronous exception is delivered


def test_a_swallowed_timeout_is_raised_again() -> None:
    swallowed = 0
    t0 = time.monotonic()
    with pytest.raises(CaseTimeout), time_limit(0.05, refire_s=0.2):
        try:
            _busy(30.0)
        except CaseTimeout:  # a finaliser's "Exception ignored in": the study would go on
            swallowed += 1
        _busy(30.0)
    assert swallowed == 1 and time.monotonic() - t0 < 10.0


def test_a_block_that_ends_in_time_is_not_interrupted_afterwards() -> None:
    with time_limit(0.3, refire_s=0.05):
        _busy(0.01)
    _busy(0.6)  # past the limit and several re-arm periods: nothing pending may fire here
