"""Parquet write/read time and size, CSV and TDMS read time, for a realistic 2000 s recording.

100 cycles of 20 s: 11 analog channels at 1 kHz (float32, quantised like the 12-bit
NI PCI-6025E with 0-10 V sensors, section 3.2.4 and Table 3.2) and 40 digital
channels at 100 Hz (valve solenoids and reed switches of 10 actuators). Baselines: the
same arrays written uncompressed with ``numpy.savez``; the CSV parsed by plain
``pandas.read_csv``; the TDMS file read by ``nptdms.TdmsFile.read``.
"""

from __future__ import annotations

import tempfile
from datetime import UTC, datetime
from pathlib import Path

import numpy as np
import pandas as pd
import pyarrow as pa
import pyarrow.csv as pa_csv
from nptdms import ChannelObject, TdmsFile, TdmsWriter
from scipy.signal import lfilter

from common import BenchResult, best_time
from pneufdd.physics.units import bar_gauge_to_pa, slpm_to_kg_s
from pneufdd.recording import (
    Channel,
    Recording,
    read_csv,
    read_parquet,
    read_tdms,
    write_parquet,
)

ACTUATORS = ("DNC", "HMPL_H", "HMPL_V", "HMPL_VS", "DRQD", "SLT", "HGD1", "HGD2", "DSL", "ADVU")


def _adc(values: np.ndarray, full_scale: float, rng: np.random.Generator) -> np.ndarray:
    """Add sensor noise of about 1 LSB and quantise to 12 bits over 0..full_scale."""
    lsb = full_scale / 4096.0
    noisy = values + rng.normal(0.0, lsb, values.size)
    return np.clip(np.round(noisy / lsb), 0, 4095) * lsb


def _first_order(target: np.ndarray, tau_s: float, rate_hz: float) -> np.ndarray:
    a = np.exp(-1.0 / (rate_hz * tau_s))
    return lfilter([1.0 - a], [1.0, -a], target, zi=[a * target[0]])[0]


def realistic_recording(seconds: float = 2000.0, cycle_s: float = 20.0, seed: int = 0) -> Recording:
    """A rig-like recording: ``seconds`` of PLC cycles (see module docstring)."""
    rng = np.random.default_rng(seed)
    fa, fd = 1000.0, 100.0
    t = np.arange(round(seconds * fa)) / fa
    td = np.arange(round(seconds * fd)) / fd
    phase, phase_d = np.mod(t, cycle_s), np.mod(td, cycle_s)
    channels: list[Channel] = []
    extend = {}
    for k, act in enumerate(ACTUATORS):
        on, off = 0.5 + 1.3 * k, 0.5 + 1.3 * k + 4.0
        extend[act] = (phase >= on) & (phase < off)
        valve_a = ((phase_d >= on) & (phase_d < off)).astype(np.uint8)
        switch_b = ((phase_d >= on + 0.4) & (phase_d < off)).astype(np.uint8)
        switch_a = ((phase_d < on) | (phase_d >= off + 0.4)).astype(np.uint8)
        channels += [
            Channel(f"U_{act}_A", valve_a, fd, "1", "digital"),
            Channel(f"U_{act}_B", (1 - valve_a).astype(np.uint8), fd, "1", "digital"),
            Channel(f"S_{act}_A", switch_a, fd, "1", "digital"),
            Channel(f"S_{act}_B", switch_b, fd, "1", "digital"),
        ]
    fills = sum(np.abs(np.diff(e.astype(float), prepend=0.0)) for e in extend.values())
    demand = _first_order(np.asarray(fills, float) * 40.0, 0.15, fa)
    supply_bar = 6.0 - 0.02 * demand
    analog: dict[str, tuple[np.ndarray, str]] = {
        "P_In": (bar_gauge_to_pa(_adc(supply_bar, 10.0, rng)), "Pa"),
        "Q_In": (slpm_to_kg_s(_adc(12.0 + 3.0 * demand, 200.0, rng)), "kg/s"),
    }
    for act in ("DNC", "HMPL_H", "DRQD", "SLT"):
        a_side = _first_order(np.where(extend[act], 6.0, 0.0), 0.08, fa)
        b_side = _first_order(np.where(extend[act], 0.0, 6.0), 0.08, fa)
        analog[f"P_{act}_A"] = (bar_gauge_to_pa(_adc(a_side, 10.0, rng)), "Pa")
        analog[f"P_{act}_B"] = (bar_gauge_to_pa(_adc(b_side, 10.0, rng)), "Pa")
        if act == "DNC":
            fill_a = np.abs(np.gradient(a_side, 1.0 / fa))
            analog["Q_DNC_A"] = (slpm_to_kg_s(_adc(2.0 * fill_a + 1.0, 200.0, rng)), "kg/s")
            stroke = _first_order(np.where(extend[act], 0.2, 0.0), 0.12, fa)
            analog["X_DNC"] = (_adc(stroke, 0.25, rng), "m")
    # 2 + 8 + 2 = 12 analog channels; drop one pressure to get the rig's 11
    analog.pop("P_SLT_B")
    channels = [
        Channel(name, values.astype(np.float32), fa, unit)
        for name, (values, unit) in analog.items()
    ] + channels
    return Recording(
        channels,
        start_time=datetime(2011, 6, 14, 9, 0, tzinfo=UTC),
        metadata={"machine": "festo-dsd", "scenario": "benchmark", "seed": seed},
    )


def run() -> list[BenchResult]:
    rec = realistic_recording()
    arrays = {n: rec.info(n).values for n in rec.channels}
    raw_bytes = sum(a.nbytes for a in arrays.values())
    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / "run.parquet"
        npz = Path(folder) / "run.npz"
        write_s = best_time(lambda: write_parquet(rec, path, overwrite=True))
        read_s = best_time(lambda: read_parquet(path))
        savez_s = best_time(lambda: np.savez(npz, **arrays))
        load_s = best_time(lambda: dict(np.load(npz)))
        size = path.stat().st_size
        assert read_parquet(path).equals(rec)
        analog = rec.analog_channels
        csv = Path(folder) / "run.csv"
        time_s = rec.channel(analog[0])[0]
        pa_csv.write_csv(pa.table({"time": time_s, **{n: rec.info(n).values for n in analog}}), csv)
        units = {n: rec.unit(n) for n in analog}
        csv_s = best_time(lambda: read_csv(csv, {n: n for n in analog}, units), repeat=1)
        pandas_s = best_time(lambda: pd.read_csv(csv), repeat=1)
        tdms = Path(folder) / "run.tdms"
        with TdmsWriter(tdms) as writer:
            writer.write_segment(
                [
                    ChannelObject(
                        "AI" if rec.info(n).kind == "analog" else "DI",
                        n,
                        rec.info(n).values,
                        properties={"wf_increment": 1.0 / rec.rate(n), "unit_string": rec.unit(n)},
                    )
                    for n in rec.channels
                ]
            )
        tdms_s = best_time(lambda: read_tdms(tdms))
        nptdms_s = best_time(lambda: TdmsFile.read(tdms))
    return [
        BenchResult("parquet size, 2000 s rig recording", size / 1e6, "MB", "raw", raw_bytes / 1e6),
        BenchResult("parquet write, 2000 s", write_s, "s", "np.savez", savez_s),
        BenchResult("parquet read, 2000 s", read_s, "s", "np.load", load_s),
        BenchResult("read_csv, 2000 s x 11 analog", csv_s, "s", "pandas.read_csv", pandas_s),
        BenchResult("read_tdms, 2000 s x 51 channels", tdms_s, "s", "TdmsFile.read", nptdms_s),
    ]


if __name__ == "__main__":
    for result in run():
        print(result.line())
