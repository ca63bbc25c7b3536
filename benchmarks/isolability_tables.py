"""Isolability tables of the built-in machines per sensor set (issue 34; docs/faults.md).

Not a benchmark (``run.py`` skips it). Per machine: two leak-free 12-cycle recordings of
its description (seeds ``S + 1``, ``S + 2``), exported as a DAQ would, make one
reference per sensor set (no leak signatures: the table simulates its own); the fault
signatures are simulated once on the ``full`` reference's features and selected per
set (:func:`pneufdd.diagnosis.isolability.isolability`), with ``--plants`` plausible
plants at scale 1 as the plant-uncertainty band; each set is judged with the true
faults at their signature size and at a third of it. Prints markdown for
``docs/faults.md``; ``--json FILE`` writes every row.

    python benchmarks/isolability_tables.py [--machines a,b] [--sets full,...] [--plants 6]
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

from pneufdd.diagnosis.isolability import LADDER, fault_signatures, isolability
from pneufdd.diagnosis.recordings import build_reference_from_recordings
from pneufdd.diagnosis.reference.sensor_sets import machine_sensor_sets
from pneufdd.files import write_text_atomic
from pneufdd.sim import as_exported, load_machine, simulate

SETS = "full,supply-only,line-flows,digital-only"


def _tables(name: str, sets: list[str], seed: int, plants: int) -> list[dict[str, object]]:
    machine = load_machine(name)
    t0 = time.perf_counter()
    recs = [as_exported(simulate(machine, cycles=12, seed=seed + k)) for k in (1, 2)]
    analog = tuple(c for c in recs[0].analog_channels)
    chosen = machine_sensor_sets(analog, sets)
    refs = {
        label: build_reference_from_recordings(
            recs, list(channels), ["ref1", "ref2"], machine=machine, with_signatures=False,
            workers=1,
        )
        for label, channels in chosen.items()
    }  # fmt: skip
    widest = max(refs.values(), key=lambda r: len(r.feature_names))
    signatures = fault_signatures(widest, plants=plants)
    out = []
    print(f"#### {name}\n")
    print(
        f"{len(signatures.members) + len(signatures.stalled)} hypotheses simulated "
        f"({len(signatures.stalled)} stop the machine: "
        f"{', '.join(m.describe() for m in signatures.stalled) or 'none'}); "
        f"{time.perf_counter() - t0:.0f} s.\n"
    )
    print("| set | size | detectable | isolable (group of one) | type isolable | component "
          "isolable | confusions across types (true -> also in group: count) |")  # fmt: skip
    print("|---|---|---|---|---|---|---|")
    groups: dict[str, list[str]] = {}
    for label, ref in refs.items():
        for scale in (1.0, LADDER[0]):
            table = isolability(ref, signatures, truth_scale=scale)
            s = table.summary()
            conf = ", ".join(
                f"{a} -> {b}: {n}" for (a, b), n in sorted(table.type_confusions().items())
            )
            print(
                f"| {label} | {scale:.2g} | {s['detectable']}/{s['hypotheses']} | "
                f"{s['isolable']} | {s['type_isolable']} | {s['component_isolable']} | "
                f"{conf or 'none'} |"
            )
            lines = []
            for i, m in enumerate(table.members):
                others = [table.members[j] for j in table.group(i)]
                if table.detectable[i] and any(o.fault_type != m.fault_type for o in others):
                    lines.append(f"{m.describe()}: {'; '.join(o.describe() for o in others)}")
                elif not table.detectable[i]:
                    lines.append(f"{m.describe()}: not detectable as an explanation")
            groups[f"{label}, size x{scale:.2g}"] = lines
            out.append({"machine": name, **table.to_dict()})
    for label, lines in groups.items():
        print(f"\n{name}, {label}: groups across types, and hypotheses not detectable\n")
        for line in lines:
            print(f"* {line}")
    print()
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--machines", default="press-fit-cell,festo-dsd,carton-sorter")
    parser.add_argument("--sets", default=SETS)
    parser.add_argument("--seed", type=int, default=3_400_000)
    parser.add_argument("--plants", type=int, default=6)
    parser.add_argument("--json", type=Path, default=None)
    args = parser.parse_args()
    rows = []
    for k, name in enumerate(args.machines.split(",")):
        rows += _tables(name, args.sets.split(","), args.seed + 10 * k, args.plants)
    if args.json is not None:
        write_text_atomic(args.json, json.dumps(rows, indent=1))


if __name__ == "__main__":
    main()
