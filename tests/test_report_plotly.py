"""The dashboard's Plotly figures keep the report's axis rules (report/plotly_figures.py)."""

from __future__ import annotations

import json
from datetime import datetime

from pneufdd.report.plotly_figures import leak_trend_figure


def _x_range_s(figure_json: str) -> float:
    layout = json.loads(figure_json)["layout"]
    low, high = (datetime.fromisoformat(v) for v in layout["xaxis"]["range"])
    return (high - low).total_seconds()


def test_one_leak_estimate_is_drawn_on_an_axis_at_least_an_hour_wide():
    trend = [
        {
            "location": "supply",
            "state": "new",
            "repaired_at": None,
            "sizes": [{"time": 1772344860.12, "flow_slpm": 109.4}],
        }
    ]
    assert _x_range_s(leak_trend_figure(trend, "festo-dsd")) >= 3600.0


def test_estimates_a_day_apart_keep_their_span_with_a_margin():
    sizes = [{"time": 1772344860.0 + 43200.0 * k, "flow_slpm": 50.0 + k} for k in range(3)]
    trend = [{"location": "DNC_B", "state": "growing", "repaired_at": None, "sizes": sizes}]
    span = _x_range_s(leak_trend_figure(trend, "festo-dsd"))
    assert 86400.0 < span <= 1.2 * 86400.0
    flows = json.loads(leak_trend_figure(trend, "festo-dsd"))["layout"]["yaxis"]["range"]
    assert flows[0] == 0.0  # a ratio quantity from zero: a 4 % change is drawn as 4 %
