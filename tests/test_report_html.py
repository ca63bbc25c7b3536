"""The HTML report is valid, self-contained, escaped and carries the table values."""

from __future__ import annotations

import base64
import html
import re
from dataclasses import replace
from html.parser import HTMLParser

import pytest

from _diag_synth import synth_signatures, synth_table
from pneufdd.diagnosis.cost import COST_BASIS_CONTINUOUS
from pneufdd.diagnosis.engine import diagnose
from pneufdd.diagnosis.reference.model import ReferenceModel
from pneufdd.report import render_report, write_report

VOID = {"meta", "img", "br", "hr", "link", "input"}


class _Checker(HTMLParser):
    def __init__(self):
        super().__init__()
        self.stack: list[str] = []
        self.errors: list[str] = []
        self.sources: list[str] = []
        self.tags: set[str] = set()

    def handle_starttag(self, tag, attrs):
        self.tags.add(tag)
        for name, value in attrs:
            if name in ("src", "href"):
                self.sources.append(value or "")
        if tag not in VOID:
            self.stack.append(tag)

    def handle_endtag(self, tag):
        if not self.stack or self.stack[-1] != tag:
            self.errors.append(f"unbalanced </{tag}> (open: {self.stack[-3:]})")
        else:
            self.stack.pop()


@pytest.fixture(scope="module")
def case():
    ref = ReferenceModel.build(
        synth_table(40, seed=100), signatures=synth_signatures(), sources=["<ref>&.parquet"]
    )
    run = synth_table(10, {"supply": 6e-4, "X_B": 1.1e-3}, seed=9)
    return ref, run, diagnose(ref, run)


def test_report_is_valid_self_contained_html(case, tmp_path):
    ref, run, result = case
    path = write_report(tmp_path / "r.html", ref, run, result, run_name="run<1>.parquet")
    text = path.read_text(encoding="utf-8")
    assert text.startswith("<!DOCTYPE html>")
    checker = _Checker()
    checker.feed(text)
    checker.close()
    assert checker.errors == []
    assert checker.stack == []
    assert {"html", "head", "body", "table", "img"} <= checker.tags
    assert checker.sources, "figures expected"
    for src in checker.sources:
        assert src.startswith("data:image/png;base64,")  # no external asset
        assert base64.b64decode(src.split(",", 1)[1])[:8] == b"\x89PNG\r\n\x1a\n"
    assert len(checker.sources) >= 4  # statistic, step means, step traces, band


def test_report_contains_table_values(case):
    ref, run, result = case
    text = render_report(ref, run, result)
    assert len(result.leaks) == 2
    for leak in result.leaks:
        assert str(leak.location) in text
        assert f"{leak.flow_slpm:,.1f}" in text
        assert f"{leak.orifice_mm:,.2f}" in text
        assert f"{leak.annual_cost:,.0f}" in text
        assert f"{leak.average_flow_slpm:,.1f}" in text
    assert f"{result.total_annual_cost:,.0f}" in text
    assert "Leak detected" in text
    assert "average flow over the cycle [SLPM]" in text
    # the case's signatures hold no mean flows per cycle: the report says so
    assert all(leak.cost_basis == COST_BASIS_CONTINUOUS for leak in result.leaks)
    assert "Costs assume continuous leakage" in text
    # the eq. 4.21 supply check and the run statistic's kind
    assert result.supply is not None
    assert result.supply.verdict == "leak (eq. 4.21 holds)"
    assert "supply check, eq. 4.21" in text
    assert "leak (eq. 4.21 holds) (cycles: leak (eq. 4.21 holds): " in text
    assert "run statistic (median T) / threshold" in text
    # what the sensor set can and cannot find (docs/sensor-sets.md)
    report = result.sensor_set
    assert report is not None
    assert report.channels == ref.channels
    assert f"<td class='l'>{report.kind}</td>" in text
    assert html.escape(report.cannot, quote=True) in text


def test_report_escapes_text(case):
    ref, run, result = case
    result = replace(result, notes=["<script>alert(1)</script>"])
    text = render_report(ref, run, result, title="A & B", run_name="run<1>.parquet")
    assert "<script>" not in text
    assert "&lt;script&gt;" in text
    assert "run&lt;1&gt;.parquet" in text
    assert "&lt;ref&gt;&amp;.parquet" in text
    assert re.search(r"<title>A &amp; B</title>", text)


def test_leak_free_report(case):
    ref, _, _ = case
    run = synth_table(10, seed=77)
    result = diagnose(ref, run)
    assert not result.detected
    text = render_report(ref, run, result)
    assert "No leak detected" in text


def _six_leaks(result):
    """``result`` with six located leaks, their totals, repair order and remainder."""
    from pneufdd.diagnosis.cost import LeakTotals
    from pneufdd.diagnosis.findings import LeakFinding
    from pneufdd.diagnosis.localisation.remainder import HiddenLeak, Remainder
    from pneufdd.location import Location

    names = ["DNC_A", "DNC_B", "HGD2_A", "HMPL_V_B", "SLT_B", "supply"]
    leaks = [
        LeakFinding(
            Location.parse(name),
            (i + 1) * 2e-4,
            (i + 1) * 1e-4,
            1e-3,
            100.0 * (6 - i),
            0.9,
            (
                Location.parse(name),
                Location.parse("DRQD_A"),
                Location.parse("DRQD_B"),
                Location.parse("SLT_A"),
            ),
            "average flow over the operating cycle",
            mass_flow_interval=((i + 1) * 1.5e-4, (i + 1) * 2.5e-4),
            repair_cost=40.0 if i % 2 else 145.0,
            repair_kind="fitting, tube, hose or coupling",
        )
        for i, name in enumerate(names)
    ]
    remainder = Remainder(
        0.88,
        (
            HiddenLeak(Location.parse("HMPL_H_A"), 2.6e-4),
            HiddenLeak(Location.parse("HGD2_B"), 1e-4),
        ),
        more_leaks_possible=True,
        reasons=("a further leak would lower the residual by 18 %",),
    )
    totals = LeakTotals(
        4.2e-3, (3.9e-3, 4.5e-3), 2.1e-3, (1.9e-3, 2.3e-3), 2100.0, (1900.0, 2300.0)
    )
    return replace(
        result, leaks=leaks, remainder=remainder, totals=totals, repair_order=(1, 3, 5, 0, 2, 4)
    )


def test_a_long_leak_list_and_its_remainder_are_reported(case):
    ref, run, result = case
    many = _six_leaks(result)
    text = render_report(ref, run, many)
    checker = _Checker()
    checker.feed(text)
    checker.close()
    assert checker.errors == []
    assert checker.stack == []
    table = text.split("<h2>Leaks, ranked by annual cost</h2>")[1].split("</table>")[0]
    assert table.count("<tr>") == 1 + 6 + 1  # the header, one row per leak, the total
    assert "HMPL_V_B" in table
    assert "27.8-46.4" in table
    remainder = text.split("<h2>What the leaks do not explain</h2>")[1].split("<h2>")[0]
    assert "more leaks may be present" in remainder
    assert "HMPL_H" in remainder
    assert "12.1" in remainder
    assert "explain 88 %" in remainder
    assert "; more leaks may be present</div>" in text  # the verdict says so too
