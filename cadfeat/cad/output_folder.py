"""Moved to ``cadfeat.study.output_folder`` (output folders are not CAD); this name stays for code written
before the move."""

from cadfeat.study.output_folder import *  # noqa: F403
from cadfeat.study.output_folder import __all__  # noqa: F401
