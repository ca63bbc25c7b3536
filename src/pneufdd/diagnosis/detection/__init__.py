"""Detection: is this run different from the leak-free machine? (ISO 13374 *detect*).

Owns the per-cycle statistics that decide whether a run deviates from its reference:
the standardised cycle distance of section 5.3.2 (:mod:`.statistic`), the band
method of eq. 5.21 (:mod:`.band`) and the residuals against a replay of the digital
twin (:mod:`.residuals`).

May import: :mod:`pneufdd.errors`, :mod:`pneufdd.recording`, :mod:`pneufdd.physics`,
:mod:`pneufdd.sim`, :mod:`pneufdd.signals` and :mod:`pneufdd.features`; nothing else
of :mod:`pneufdd.diagnosis`.
"""
