"""Package-level checks: light import, CLI help."""

import subprocess
import sys


def test_import_is_light():
    code = "import sys, cadfeat; print('cadquery' in sys.modules, 'pyvista' in sys.modules)"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.split() == ["False", "False"]


def test_cli_help_lists_commands():
    out = subprocess.run([sys.executable, "-m", "cadfeat.cli", "--help"], capture_output=True, text=True,
                         check=True).stdout
    assert "cameras" in out
