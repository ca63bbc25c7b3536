"""The issue-33/34 rig end to end through the CLI, as a user would run it.

The rig (``tests/data/triggered-rig.toml``): one DSNU-20-200 on a 5/2 double-solenoid
valve, meter-out throttles and PPV cushioning at both ends; 10 s triggered captures at
1 kHz, each holding one cycle and the idle time after it (the plant waits ~9 s for the
next part, the description knows only its 0.5 s timer), the retract solenoid on at
t = 0 (0.22 s pre-trigger), ``P_In`` quantised in 0.19 bar steps; the sensor set
``P_In``, ``Q_CYL_A`` (the flows into and out of chamber A), ``X_CYL``, both solenoids
and both end switches, no supply flow meter.

Per plant (the rig varied at plant scale 1, so the reference is not the plant's twin)::

    pneufdd machine vary idle.toml --scale 1 --seed S --out plant.toml
    pneufdd simulate --machine plant.toml --capture triggered --files 20 \\
        --cycles-per-file 1 --pre-trigger-s 0.22 --capture-s 10 --quantize P_In=0.19bar \\
        --seed S+1 --out ref
    pneufdd machine draft ref/capture_0001.parquet ref/capture_0002.parquet \\
        ref/capture_0003.parquet --out draft.toml
    pneufdd reference build ref --machine rig.toml --channels P_In,Q_CYL_A,X_CYL \\
        --out rig.pnref
    pneufdd simulate ... --seed S+2 --out healthy          # held-out healthy captures
    pneufdd simulate ... --seed S+10+k --fault SETTING --out setting_k
    pneufdd diagnose CAPTURE --reference rig.pnref --json CAPTURE.json   # each alone

and counts: healthy captures flagged; per throttle/cushion setting, captures flagged,
reported with the right type first (``throttle`` or ``cushion``), with a throttle or
cushion first (the two the signals often cannot tell apart), with the true type in the
first finding's ambiguity group, on the right actuator, and reported as a leak.

Run (docs/results/900M-field-rig.md)::

    nice -n 10 python benchmarks/acceptance_field_rig.py --seed 900000000 --plants 2
"""

from __future__ import annotations

import argparse
import json
import tempfile
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from pneufdd.cli.app import main

RIG = Path(__file__).resolve().parent.parent / "tests" / "data" / "triggered-rig.toml"
CAPTURE = [
    "--capture", "triggered", "--cycles-per-file", "1", "--pre-trigger-s", "0.22",
    "--capture-s", "10", "--quantize", "P_In=0.19bar",
]  # fmt: skip
CHANNELS = "P_In,Q_CYL_A,X_CYL"
SETTINGS = (
    "CYL_B=throttle:-40%",
    "CYL_B=throttle:-70%",
    "CYL_B=throttle:+100%",
    "CYL_A=throttle:-50%",
    "CYL_B=cushion:-80%",
    "CYL_B=cushion:-92%",
    "CYL_A=cushion:-90%",
)
"""Meter-out throttle closed, opened, and cushion screws set too tight, per line."""


def _cli(args: Sequence[str]) -> int:
    code = main([str(a) for a in args])
    if code not in (0, 1):
        raise SystemExit(f"pneufdd {' '.join(map(str, args))}: exit {code}")
    return code


def _diagnose(capture: Path, reference: Path) -> dict[str, Any]:
    out = capture.with_suffix(".json")
    code = _cli(["diagnose", capture, "--reference", reference, "--json", out])
    result: dict[str, Any] = json.loads(out.read_text())
    result["exit_code"] = code
    return result


def _judge(result: dict[str, Any], kind: str, location: str) -> dict[str, bool]:
    findings = result.get("findings") or []
    first = findings[0] if findings else {}
    group = first.get("ambiguity_group") or []
    actuator = location.split("_")[0]
    return {
        "flagged": result["exit_code"] == 1,
        "type_first": first.get("type") == kind,
        "throttle_or_cushion_first": first.get("type") in ("throttle", "cushion"),
        "type_in_group": any(m.get("type") == kind for m in group),
        "right_actuator": str(first.get("location", "")).startswith(actuator)
        or str(first.get("location", "")).startswith(f"S_{actuator}"),
        "leak": bool(result.get("leaks")) or any(f.get("type") == "leak" for f in findings),
    }


def plant(root: Path, seed: int, args: argparse.Namespace) -> dict[str, Any]:
    """One plant: reference, held-out healthy captures and every setting."""
    root.mkdir(parents=True)
    text = RIG.read_text()
    idle = text.replace('wait = ["S_CYL_A"]\ndwell_s = 0.5', 'wait = ["S_CYL_A"]\ndwell_s = 9.0')
    assert idle != text
    (root / "idle.toml").write_text(idle)
    (root / "rig.toml").write_text(text)
    plant_toml, ref, pnref = root / "plant.toml", root / "ref", root / "rig.pnref"
    _cli(["machine", "vary", root / "idle.toml", "--scale", "1", "--seed", seed,
          "--out", plant_toml])  # fmt: skip
    sim = ["simulate", "--machine", plant_toml, *CAPTURE]
    _cli([*sim, "--files", args.reference_captures, "--seed", seed + 1, "--out", ref])
    draft = root / "draft.toml"
    firsts = [ref / f"capture_{k:04d}.parquet" for k in (1, 2, 3)]
    _cli(["machine", "draft", *firsts, "--out", draft])
    drafted = draft.read_text()
    draft_ok = (
        'do = [{ set = "U_CYL_A" }, { reset = "U_CYL_B" }]' in drafted
        and 'do = [{ reset = "U_CYL_A" }, { set = "U_CYL_B" }]' in drafted
    )
    _cli(["reference", "build", ref, "--machine", root / "rig.toml", "--channels", CHANNELS,
          "--out", pnref])  # fmt: skip
    healthy = root / "healthy"
    _cli([*sim, "--files", args.healthy, "--seed", seed + 2, "--out", healthy])
    free = []
    for capture in sorted(healthy.glob("*.parquet")):
        result = _diagnose(capture, pnref)
        free.append({"capture": capture.name, "flagged": result["exit_code"] == 1,
                     "statistic": result["detection"]["run_score"],
                     "threshold": result["detection"]["run_threshold"]})  # fmt: skip
    settings = []
    for k, spec in enumerate(args.settings):
        location, _, rest = spec.partition("=")
        kind = rest.split(":")[0]
        folder = root / f"setting_{k}"
        _cli([*sim, "--files", args.fault_captures, "--seed", seed + 10 + k, "--fault", spec,
              "--out", folder])  # fmt: skip
        for capture in sorted(folder.glob("*.parquet")):
            result = _diagnose(capture, pnref)
            findings = result.get("findings") or []
            settings.append(
                {
                    "setting": spec,
                    "capture": capture.name,
                    "statistic": result["detection"]["run_score"],
                    "threshold": result["detection"]["run_threshold"],
                    "reported": [f.get("text") for f in findings],
                    **_judge(result, kind, location),
                }
            )  # fmt: skip
    return {"seed": seed, "draft_ok": draft_ok, "healthy": free, "settings": settings}


def _count(rows: list[dict[str, Any]], key: str) -> str:
    return f"{sum(bool(r[key]) for r in rows)}/{len(rows)}"


def report(plants: list[dict[str, Any]]) -> str:
    """The figures as markdown lines."""
    healthy = [r for p in plants for r in p["healthy"]]
    rows = [r for p in plants for r in p["settings"]]
    lines = [
        f"plants: {len(plants)}; drafts with the right two steps: "
        f"{sum(p['draft_ok'] for p in plants)}/{len(plants)}",
        f"held-out healthy captures flagged: {_count(healthy, 'flagged')} (largest statistic "
        f"/ threshold {max((r['statistic'] / r['threshold'] for r in healthy), default=0):.2f})",
        "",
        "| setting | flagged | right type first | throttle or cushion first | true type in "
        "group | right actuator | reported as a leak |",
        "|---|---|---|---|---|---|---|",
    ]
    keys = ("flagged", "type_first", "throttle_or_cushion_first", "type_in_group",
            "right_actuator", "leak")  # fmt: skip
    for spec in dict.fromkeys(r["setting"] for r in rows):
        sub = [r for r in rows if r["setting"] == spec]
        lines.append(f"| `{spec}` | " + " | ".join(_count(sub, k) for k in keys) + " |")
    lines.append("| all | " + " | ".join(_count(rows, k) for k in keys) + " |")
    return "\n".join(lines)


def _parse(argv: Sequence[str] | None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--seed", type=int, required=True, help="first seed; plant p uses "
                        "seed + 1000 p and the next 100")  # fmt: skip
    parser.add_argument("--plants", type=int, default=2)
    parser.add_argument("--reference-captures", type=int, default=20)
    parser.add_argument("--healthy", type=int, default=10)
    parser.add_argument("--fault-captures", type=int, default=3)
    parser.add_argument("--settings", default=",".join(SETTINGS))
    parser.add_argument("--out", type=Path, default=None, help="folder kept (default: temp)")
    parser.add_argument("--json", type=Path, default=None, help="write every row here")
    args = parser.parse_args(argv)
    args.settings = [s for s in args.settings.split(",") if s]
    return args


def run(argv: Sequence[str] | None = None) -> list[dict[str, Any]]:
    """Run the measurement; print and return the per-plant rows."""
    args = _parse(argv)
    start = time.perf_counter()
    with tempfile.TemporaryDirectory() as tmp:
        base = args.out or Path(tmp)
        plants = [plant(base / f"plant{p}", args.seed + 1000 * p, args) for p in range(args.plants)]
    print(report(plants))
    print(f"({time.perf_counter() - start:.0f} s)")
    if args.json:
        args.json.write_text(json.dumps(plants, indent=1))
    return plants


if __name__ == "__main__":
    run()
