"""``pickstop ui``: bad options exit 2 naming them; ``--robot`` with a config file registers it
with the API."""

from __future__ import annotations

import pytest

from tests.cli.conftest import exit_code


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["ui", "--draft-scale", "0"], "--draft-scale: must be in (0, 1], got 0"),
        (["ui", "--draft-scale", "1.5"], "must be in (0, 1], got 1.5"),
        (["ui", "--lighting", "dark"], "--lighting: invalid choice: 'dark'"),
    ],
)
def test_bad_arguments_exit_2(tmp_path, capsys, argv, message):
    assert exit_code("--data-dir", str(tmp_path), *argv) == 2
    assert message in capsys.readouterr().err


def test_ui_robot_option_registers_a_config_with_the_api(tmp_path):
    import httpx

    from pickstop.cli.service import _api_robot
    from pickstop_ui.client import PickStopClient
    from tests.robot.synthetic import write_dense_robot

    config = write_dense_robot(tmp_path, triangles=500, arm_mesh=False)
    posted = []

    def api(request: httpx.Request) -> httpx.Response:
        if request.method == "GET":
            return httpx.Response(200, json=[{"name": "tiago"}])
        posted.append((request.headers["content-type"], request.content))
        return httpx.Response(201, json={"name": "dense_amr"})

    client = PickStopClient("http://api")
    client.http = httpx.Client(base_url="http://api", transport=httpx.MockTransport(api))
    assert _api_robot(client, "tiago") == "tiago" and not posted  # a preset: as it is
    assert _api_robot(client, str(config)) == "dense_amr"
    assert posted == [("application/yaml", config.read_bytes())]
