"""Localisation: which leaks, where and how big, explain a detected deviation.

Owns the search over leak explanations (:mod:`.search`, sections 5.3.1.2-5.3.1.5,
eqs. 5.23-5.24), the choice between explanations of different order and the ambiguity
groups (:mod:`.model_choice`) and the check of the best explanations by simulation
with the digital twin (:mod:`.check`).

May import: :mod:`pneufdd.diagnosis.effects` and the layers below
:mod:`pneufdd.diagnosis`; not :mod:`pneufdd.diagnosis.detection` or
:mod:`pneufdd.diagnosis.reference`.
"""
