"""``pneufdd energy`` end to end: a reference's diagnosis, the JSON, the report in a browser.

One press-fit-cell run with a supply leak, its reference built from two leak-free
recordings (small signature set: the leak must be found and sized, not measured
precisely), and one ``pneufdd energy`` call shared by the tests.
"""

from __future__ import annotations

import json
import re
import shutil
import subprocess
from pathlib import Path

import pytest

from pneufdd.cli.app import main
from pneufdd.sim import load_machine, simulate

SEED = 37_000  # this file's seeds: SEED + k
CHROMIUM = shutil.which("chromium") or shutil.which("chromium-browser")


@pytest.fixture(scope="module")
def energy_run(tmp_path_factory):
    folder = tmp_path_factory.mktemp("energy")
    free = []
    for k in (1, 2):
        path = folder / f"free{k}.parquet"
        simulate("press-fit-cell", cycles=6, seed=SEED + k).write(path)
        free.append(str(path))
    run = folder / "run.parquet"
    simulate("press-fit-cell", cycles=8, leaks={"supply": "25slpm"}, seed=SEED + 3).write(run)
    ref = folder / "ref.pnref"
    built = main(
        ["reference", "build", *free, "--out", str(ref), "--signature-sizes", "8,30,80",
         "--uncertainty-plants", "1", "--signature-cycles", "1"]
    )  # fmt: skip
    assert built == 0
    out = {"json": folder / "energy.json", "report": folder / "energy.html", "run": run}
    code = main(
        ["energy", str(run), "--reference", str(ref), "--json", str(out["json"]),
         "--report", str(out["report"])]
    )  # fmt: skip
    assert code == 0
    out["data"] = json.loads(out["json"].read_text())
    return out


def test_energy_json_answers_the_issue(energy_run):
    data = energy_run["data"]
    press = load_machine("press-fit-cell")
    assert data["supply_pressure_now_bar_g"] == pytest.approx(6.0, abs=0.01)  # 87 psig
    assert 1.0 < data["supply_pressure_min_bar_g"] < data["supply_pressure_now_bar_g"]
    assert data["limiting_actuator"] in press.actuator_ids
    assert data["saving_per_year"] > 0
    names = {m["name"] for m in data["measures"]}
    assert {"lower the set point", "shorter tubes", "air off at standstill"} <= names
    savings = [m["saving_per_year"] for m in data["measures"] if m["feasible"]]
    assert savings == sorted(savings, reverse=True)
    breakdown = data["breakdown"]
    # the diagnosis's supply leak is in the twin and in the breakdown
    assert [k["location"] for k in breakdown["leaks"]] == ["supply"]
    assert "leak.supply" in breakdown["by_group_kg"]
    assert set(breakdown["by_actuator_kg"]) == set(press.actuator_ids)
    air = breakdown["air_per_cycle_kg"]
    assert air["explained"] == pytest.approx(air["measured"], rel=0.03)
    # a leak blows at standstill: switching the air off saves money
    off = next(m for m in data["measures"] if m["kind"] == "air_off")
    assert off["saving_per_year"] > 0


def test_energy_cli_refuses_bad_input(energy_run, tmp_path, capsys):
    run = str(energy_run["run"])
    assert main(["energy", run]) == 2
    assert "--machine" in capsys.readouterr().err
    assert main(["energy", run, "--machine", "press-fit-cell", "--leak", "supply"]) == 2
    assert "LOCATION=MM" in capsys.readouterr().err
    code = main(["energy", run, "--machine", "press-fit-cell", "--json", str(energy_run["json"])])
    assert code == 2  # an existing output is not replaced unasked
    assert main(["energy", run, "--machine", "press-fit-cell", "--tolerance", "2"]) == 2


@pytest.mark.skipif(CHROMIUM is None, reason="chromium is not installed (apt: chromium)")
def test_energy_report_renders_in_the_browser(energy_run, tmp_path):
    """The report in headless chromium: both figures decode, the table and headline show."""
    assert CHROMIUM is not None
    report: Path = energy_run["report"]
    dom = subprocess.run(
        [CHROMIUM, "--headless", "--no-sandbox", "--disable-gpu",
         "--disable-background-networking", f"--user-data-dir={tmp_path / 'profile'}",
         "--virtual-time-budget=5000", "--dump-dom", report.as_uri()],
        capture_output=True, text=True, timeout=120, check=True,
    ).stdout  # fmt: skip
    data = energy_run["data"]
    assert 'data-figures-rendered="2"' in dom
    sizes = re.findall(r'data-rendered="(\d+)x(\d+)"', dom)
    assert len(sizes) == 2
    assert all(int(w) > 400 and int(h) > 150 for w, h in sizes)
    assert f'<span id="limiting">{data["limiting_actuator"]}</span>' in dom
    minimum = f"{data['supply_pressure_min_bar_g']:.2f}"
    assert f'<span id="min-pressure">{minimum}</span>' in dom
    table = dom[dom.index('id="measures"') :]
    table = table[: table.index("</table>")]
    assert table.count("<tr") == len(data["measures"]) + 1
    assert "Where the air goes" in dom
    assert "leak.supply" in dom
