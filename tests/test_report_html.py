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
