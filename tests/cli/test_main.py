"""The ``pickstop`` entry point: an unknown command exits 2, ``python -m pickstop.cli`` runs it."""

from __future__ import annotations

import json
import subprocess
import sys

from tests.cli.conftest import exit_code


def test_an_unknown_command_exits_2(tmp_path, capsys):
    assert exit_code("--data-dir", str(tmp_path), "nonsense") == 2
    assert "invalid choice" in capsys.readouterr().err


def test_console_script_installed(tmp_path):
    proc = subprocess.run(
        [sys.executable, "-m", "pickstop.cli", "--data-dir", str(tmp_path), "reach", "info"],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert proc.returncode == 0 and json.loads(proc.stdout) == []
