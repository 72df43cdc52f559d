"""What ships: the demo starts API and planner; the compose file matches the CLI and README."""

from __future__ import annotations

import re
import subprocess
import sys
import time
from pathlib import Path

import httpx
import pytest
import yaml

from pickstop.cli import build_parser
from tests.conftest import free_port

ROOT = Path(__file__).parents[1]


def test_demo_answers_health_and_serves_the_planner(tmp_path):
    api, ui = free_port(), free_port()
    proc = subprocess.Popen(
        [sys.executable, "-m", "pickstop.cli", "--data-dir", str(tmp_path), "demo", "--samples",
         "300000", "--port", str(api), "--ui-port", str(ui)],
        stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True,
    )  # fmt: skip
    try:
        lines = []
        t0 = time.time()
        while time.time() - t0 < 300:
            line = proc.stdout.readline()
            if not line:
                break
            lines.append(line)
            if "Press Ctrl-C" in line:
                break
        text = "".join(lines)
        assert "PickStop demo" in text, text
        api_url = re.search(r"REST API:\s+(\S+)/api/v1/docs", text).group(1)
        ui_url = re.search(r"3D planner:\s+(\S+)", text).group(1)
        health = httpx.get(f"{api_url}/api/v1/health", timeout=10).json()
        assert health["status"] == "ok" and health["loaded"]
        page = httpx.get(ui_url, timeout=10)
        assert page.status_code == 200 and "<html" in page.text.lower()
        assert "paper-experiment" in text
    finally:
        proc.terminate()
        try:
            proc.wait(timeout=30)
        except subprocess.TimeoutExpired:
            proc.kill()


@pytest.fixture(scope="module")
def compose():
    return yaml.safe_load((ROOT / "docker-compose.yml").read_text())


def _command(service: dict) -> list[str]:
    cmd = service["command"]
    return cmd if isinstance(cmd, list) else cmd.split()


def test_compose_services_run_real_cli_commands(compose):
    services = compose["services"]
    assert {"api", "ui"} <= set(services)
    assert {"dask-scheduler", "dask-worker"} <= {
        n for n, s in services.items() if "dask" in s.get("profiles", [])
    }
    parser = build_parser()
    for name in ("api", "ui"):
        cmd = _command(services[name])
        shell = cmd[:2] == ["sh", "-c"]
        parts = [p.split() for p in cmd[2].split("&&")] if shell else [cmd]
        for part in parts:
            assert part[0] == "pickstop", part
            parser.parse_args(part[1:])  # exits (fails the test) on an unknown command or flag


def test_compose_ports_and_volume_match_the_readme(compose):
    readme = (ROOT / "README.md").read_text()
    services = compose["services"]
    assert services["api"]["ports"] == ["8000:8000"] and "8000" in readme
    assert services["ui"]["ports"] == ["8080:8080"] and "8080" in readme
    assert "pickstop-data" in compose["volumes"] and "pickstop-data" in readme
    for name in ("api", "dask-worker"):
        assert "pickstop-data:/data" in services[name]["volumes"]
    assert "docker compose up" in readme and "--profile dask" in readme
    dockerfile = (ROOT / "Dockerfile").read_text()
    assert "pip install" in dockerfile and "pyproject.toml" in dockerfile


def test_ci_runs_exactly_the_readme_test_command():
    readme = (ROOT / "README.md").read_text()
    blocks = re.findall(r"```bash\n(.*?)\n```", readme, flags=re.S)
    assert blocks[0] == "pip install -e . && pickstop demo"
    ci = (ROOT / ".ci" / "run").read_text().strip().splitlines()[-1]
    assert blocks[1] == ci and ci.endswith("python -m pytest")
