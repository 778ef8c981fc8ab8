"""Sub-command ``cadfeat plan-recording STUDY``: what to send the robot and print before recording in a real cell."""

from __future__ import annotations

COMMANDS: tuple = ()
