"""``pickstop layout``: suggestions written to a file with a summary on stdout; a tray no order
needs exits 2."""

from __future__ import annotations

import json

from tests.cli.conftest import EXAMPLES, run


def test_layout_suggestions_to_a_file(region_db, tmp_path, capsys):
    folder, db = region_db
    out = tmp_path / "layout.json"
    code, stdout, _ = run(
        capsys, "--data-dir", str(folder), "layout", str(EXAMPLES / "paper_experiment.json"),
        "--movable", "tray_4", "--turns", "0", "--step", "0.2", "--samples", "0",
        "--suggestions", "1", "--shortlist", "4", "--out", str(out), "--db", db.id, "--quiet",
    )  # fmt: skip
    assert code == 0
    summary, doc = json.loads(stdout), json.loads(out.read_text())
    assert doc["format"] == "pickstop.layout" and summary["out"] == str(out)
    assert summary["before"] == doc["before"]["totals"] and doc["orders"] == ["task"]
    code, _, err = run(capsys, "--data-dir", str(folder), "layout",
                        str(EXAMPLES / "paper_experiment.json"), "--movable", "tray_3")  # fmt: skip
    assert code == 2 and "no order needs tray 'tray_3'" in err
