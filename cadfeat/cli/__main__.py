"""``python -m cadfeat.cli`` is the ``cadfeat`` command."""

import sys

from cadfeat.cli import main

sys.exit(main())
