"""`trials lattice`: SBPL problems from their files, text and JSON, and its answers to bad input."""

from __future__ import annotations

import json

import pytest

from trials.cli import main


def test_text_report_lists_every_epsilon_then_the_path(sbpl_dir, capsys):
    code = main(["lattice", str(sbpl_dir / "env1.cfg"), str(sbpl_dir / "pr2.mprim"), "--point"])
    out = capsys.readouterr().out.splitlines()
    assert code == 0
    assert out[0].startswith("env1.cfg + pr2.mprim: 15 x 15 cells of 0.025 m, 16 headings, 7 primitives per heading")
    rows = [line.split() for line in out[out.index(next(line for line in out if line.split()[:2] == ["eps", "cost"])) + 1:]
            if len(line.split()) == 4 and line.split()[0][0].isdigit() and "." in line.split()[0]]
    assert float(rows[0][0]) == 3.0 and float(rows[-1][0]) == 1.0 and rows[-1][1] == "8348"
    assert "status: solved: path of cost 8348 within eps 1 of optimal" in out
    path = [tuple(map(float, line.split())) for line in out[out.index("path (x y theta):") + 1:]]
    assert path[0][:2] == pytest.approx((0.1125, 0.1125)) and path[-1][:2] == pytest.approx((0.3375, 0.2875))


def test_json_report(sbpl_dir, capsys):
    code = main(["lattice", str(sbpl_dir / "ped2_10cm.cfg"), str(sbpl_dir / "pr2_10cm.mprim"), "--json",
                 "--eps", "2.0", "--eps-step", "0.5"])
    report = json.loads(capsys.readouterr().out)
    assert code == 0 and report["status"] == "solved"
    assert [it["eps"] for it in report["iterations"]] == [2.0, 1.5, 1.0]
    assert set(report["iterations"][0]) == {"eps", "cost", "expansions", "seconds"}
    assert report["iterations"][-1]["cost"] == report["cost"] == 19744  # SBPL's optimum (default footprint)
    assert report["heuristic_seconds"] > 0 and len(report["path"][0]) == 3
    assert report["start"] == [10, 50, 0] and report["goal"] == [190, 50, 0]


def test_relative_files_are_read_from_the_study_folder(sbpl_dir, capsys):
    assert main(["lattice", "ped2_10cm.cfg", "pr2_10cm.mprim", "--study", str(sbpl_dir), "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["goal"] == [190, 50, 0]


@pytest.mark.parametrize("args, message", [
    (["--footprint", "0.5,0.3 -0.5"], 'error: --footprint: expected points "x,y" separated by spaces, got "-0.5"'),
    (["--footprint", "0,0 1,1"], "error: --footprint: a polygon needs at least 3 points, got 2 (use --point "
     "for a point robot)"),
    (["--eps", "0.5"], "error: --eps: expected a number of at least 1, got 0.5"),
    (["--budget", "0"], "error: --budget: expected a positive number of seconds, got 0.0"),
])
def test_bad_options_exit_2_with_one_line(sbpl_dir, capsys, args, message):
    code = main(["lattice", str(sbpl_dir / "env1.cfg"), str(sbpl_dir / "pr2.mprim"), *args])
    err = capsys.readouterr().err
    assert code == 2 and err.strip() == message


def test_mismatched_files_exit_2(sbpl_dir, capsys):
    code = main(["lattice", str(sbpl_dir / "env1.cfg"), str(sbpl_dir / "pr2_10cm.mprim")])
    err = capsys.readouterr().err
    assert code == 2
    assert err.strip() == "error: the primitives' resolution 0.1 m does not match the environment's cell size 0.025 m"


def test_malformed_file_exits_2_naming_its_line(sbpl_dir, tmp_path, capsys):
    bad = tmp_path / "broken.cfg"
    bad.write_text((sbpl_dir / "env1.cfg").read_text().replace("obsthresh: 1", "obsthresh: one"))
    code = main(["lattice", str(bad), str(sbpl_dir / "pr2.mprim")])
    err = capsys.readouterr().err
    assert code == 2 and "Traceback" not in err
    assert err.strip() == 'error: broken.cfg, line 2: expected the obstacle threshold (an integer in 0..255), got "one"'


def test_unreachable_request_exits_1_with_its_status(sbpl_dir, tmp_path, capsys):
    outside = tmp_path / "outside.cfg"
    outside.write_text((sbpl_dir / "env1.cfg").read_text().replace("end(meters,rads): 0.35 0.3 0",
                                                                   "end(meters,rads): 0.5 0.3 0"))
    code = main(["lattice", str(outside), str(sbpl_dir / "pr2.mprim"), "--point", "--json"])
    report = json.loads(capsys.readouterr().out)
    assert code == 1 and report["status"] == "goal_outside_map" and report["path"] == []
    assert report["message"] == "the goal cell (20, 11) is outside the 15 x 15 map"
