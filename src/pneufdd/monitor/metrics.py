"""Prometheus metrics (prometheus-client): cycles, alarms and leak flow per machine.

Two sources, the same names where they mean the same thing:

- :class:`MonitorMetrics`, a running monitor's own registry (``pneufdd monitor
  --metrics-port``, loopback only): counters updated with every cycle it processes;
- :func:`history_metrics`, read from the history by ``pneufdd serve`` at each scrape
  (``GET /metrics``, behind the dashboard's authentication): the fleet view's
  aggregates, never a scan of the cycles.

=====================================  =========  ==========================================
name                                   type       labels, meaning
=====================================  =========  ==========================================
``pneufdd_cycles_total``               counter    machine; cycles processed (monitor)
``pneufdd_cycles_last_24h``            gauge      machine; cycles recorded in the last 24 h
``pneufdd_last_cycle_timestamp_seconds`` gauge    machine; start of the newest cycle
``pneufdd_alarms_total``               counter    machine, kind (``leak``/``repaired``)
``pneufdd_open_alarms``                gauge      machine; leak alarms not acknowledged
``pneufdd_in_alarm``                   gauge      machine; 1 while a leak is declared
``pneufdd_cycle_score``                gauge      machine; newest cycle's score T (monitor)
``pneufdd_cusum``                      gauge      machine; CUSUM after the newest cycle
``pneufdd_leak_flow_slpm``             gauge      machine, location; active leak's flow while
                                                  pressurised [SLPM: 0 degC, 1013 mbar]
``pneufdd_leak_annual_cost_dollars``   gauge      machine, location; its cost [$/yr]
``pneufdd_gaps_total``                 counter    machine; gaps recorded (history)
=====================================  =========  ==========================================
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Iterator, Mapping
from typing import Any

from prometheus_client import CollectorRegistry, Counter, Gauge
from prometheus_client.core import CounterMetricFamily, GaugeMetricFamily, Metric
from prometheus_client.exposition import CONTENT_TYPE_LATEST, generate_latest

from pneufdd.monitor.database import HistoryDatabase

__all__ = ["MonitorMetrics", "history_metrics"]


class MonitorMetrics:
    """A running monitor's metrics, updated by :meth:`update` after every cycle.

    A :class:`~pneufdd.monitor.publish.Publisher`; :meth:`serve` exposes it over HTTP
    on the loopback interface only (prometheus-client's server has no authentication).
    """

    name = "metrics"

    def __init__(self) -> None:
        self._server: Any = None
        self.registry = CollectorRegistry()
        r = self.registry
        self.cycles = Counter("pneufdd_cycles", "Cycles processed.", ["machine"], registry=r)
        self.alarms = Counter("pneufdd_alarms", "Alarms raised.", ["machine", "kind"], registry=r)
        self.in_alarm = Gauge(
            "pneufdd_in_alarm", "1 while a leak is declared.", ["machine"], registry=r
        )
        self.score = Gauge(
            "pneufdd_cycle_score", "Newest cycle's score T.", ["machine"], registry=r
        )
        self.cusum = Gauge(
            "pneufdd_cusum", "CUSUM after the newest cycle.", ["machine"], registry=r
        )
        self.last = Gauge(
            "pneufdd_last_cycle_timestamp_seconds",
            "Start of the newest cycle.",
            ["machine"],
            registry=r,
        )
        self.flow = Gauge(
            "pneufdd_leak_flow_slpm",
            "Active leak's flow while pressurised [SLPM at 0 degC, 1013 mbar].",
            ["machine", "location"],
            registry=r,
        )
        self.cost = Gauge(
            "pneufdd_leak_annual_cost_dollars",
            "Active leak's annual cost [$/yr].",
            ["machine", "location"],
            registry=r,
        )
        self._locations: dict[str, set[str]] = {}

    def update(self, snapshot: Mapping[str, Any]) -> None:
        """Take one cycle's snapshot (:func:`pneufdd.monitor.publish.snapshot`)."""
        machine = str(snapshot["machine"])
        self.cycles.labels(machine).inc()
        for alarm in snapshot.get("new_alarms", []):
            self.alarms.labels(machine, str(alarm["kind"])).inc()
        self.in_alarm.labels(machine).set(1.0 if snapshot["in_alarm"] else 0.0)
        score = snapshot.get("score")
        self.score.labels(machine).set(math.nan if score is None else float(score))
        self.cusum.labels(machine).set(float(snapshot["cusum"]))
        self.last.labels(machine).set(float(snapshot["last_cycle"]))
        now = set()
        for finding in snapshot["findings"]:
            location = str(finding["location"])
            now.add(location)
            flow, cost = finding.get("flow_slpm"), finding.get("annual_cost")
            self.flow.labels(machine, location).set(math.nan if flow is None else flow)
            self.cost.labels(machine, location).set(math.nan if cost is None else cost)
        for gone in self._locations.get(machine, set()) - now:
            self.flow.remove(machine, gone)
            self.cost.remove(machine, gone)
        self._locations[machine] = now

    def publish(self, state: Mapping[str, Any], diagnosis: Mapping[str, Any] | None) -> None:
        """Publisher interface: :meth:`update`."""
        self.update(state)

    def serve(self, port: int, host: str = "127.0.0.1") -> None:
        """Answer ``GET /metrics`` on ``host:port`` (a loopback address only)."""
        from prometheus_client import start_http_server

        from pneufdd.monitor.credentials import check_bind

        check_bind("--metrics-port host", host, authenticated=False)
        self._server, _thread = start_http_server(port, addr=host, registry=self.registry)

    def close(self) -> None:
        """Stop the HTTP server, if any."""
        if self._server is not None:
            self._server.shutdown()
            self._server.server_close()
            self._server = None

    def text(self) -> bytes:
        """The registry in Prometheus text format."""
        return bytes(generate_latest(self.registry))


class _HistoryCollector:
    def __init__(self, db: HistoryDatabase, now: float) -> None:
        self.db, self.now = db, now

    def collect(self) -> Iterator[Metric]:
        import sqlalchemy as sa

        from pneufdd.monitor.database import alarms, leaks
        from pneufdd.monitor.fleet import fleet_summary

        rows = fleet_summary(self.db, self.now)
        names = {r.machine_id: r.name for r in rows}
        recent = GaugeMetricFamily(
            "pneufdd_cycles_last_24h", "Cycles recorded in the last 24 h.", labels=["machine"]
        )
        last = GaugeMetricFamily(
            "pneufdd_last_cycle_timestamp_seconds",
            "Start of the newest recorded cycle.",
            labels=["machine"],
        )
        in_alarm = GaugeMetricFamily(
            "pneufdd_in_alarm", "1 while a leak is declared.", labels=["machine"]
        )
        open_alarms = GaugeMetricFamily(
            "pneufdd_open_alarms", "Leak alarms not acknowledged.", labels=["machine"]
        )
        gaps = CounterMetricFamily("pneufdd_gaps", "Gaps recorded.", labels=["machine"])
        for r in rows:
            recent.add_metric([r.name], r.cycles_24h)
            if r.last_cycle is not None:
                last.add_metric([r.name], r.last_cycle)
            in_alarm.add_metric([r.name], 1.0 if r.in_alarm else 0.0)
            open_alarms.add_metric([r.name], r.open_alarms)
            gaps.add_metric([r.name], r.gaps)
        counted = CounterMetricFamily(
            "pneufdd_alarms", "Alarms raised.", labels=["machine", "kind"]
        )
        flow = GaugeMetricFamily(
            "pneufdd_leak_flow_slpm",
            "Active leak's flow while pressurised [SLPM at 0 degC, 1013 mbar].",
            labels=["machine", "location"],
        )
        cost = GaugeMetricFamily(
            "pneufdd_leak_annual_cost_dollars",
            "Active leak's annual cost [$/yr].",
            labels=["machine", "location"],
        )
        with self.db.engine.connect() as conn:
            for machine_id, kind, count in conn.execute(
                sa.select(alarms.c.machine_id, alarms.c.kind, sa.func.count()).group_by(
                    alarms.c.machine_id, alarms.c.kind
                )
            ):
                counted.add_metric([names.get(machine_id, str(machine_id)), str(kind)], count)
            for machine_id, location, slpm, dollars in conn.execute(
                sa.select(
                    leaks.c.machine_id, leaks.c.location, leaks.c.flow_slpm, leaks.c.annual_cost
                ).where(leaks.c.state != "repaired")
            ):
                name = names.get(machine_id, str(machine_id))
                flow.add_metric([name, str(location)], math.nan if slpm is None else slpm)
                cost.add_metric([name, str(location)], math.nan if dollars is None else dollars)
        metrics: Iterable[Metric] = (recent, last, in_alarm, open_alarms, gaps, counted, flow, cost)
        yield from metrics


def history_metrics(db: HistoryDatabase, now: float) -> tuple[bytes, str]:
    """The history's metrics in Prometheus text format, and its content type."""
    registry = CollectorRegistry(auto_describe=False)
    registry.register(_HistoryCollector(db, now))
    return bytes(generate_latest(registry)), str(CONTENT_TYPE_LATEST)
