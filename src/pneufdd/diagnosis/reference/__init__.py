"""The reference: what a leak-free machine looks like, and the ``.pnref`` file.

Owns :class:`ReferenceModel` (:mod:`.model`: the leak-free statistics, the detection
settings and threshold, the leak-effect model and the machine description it was built
with) and its file format (:mod:`.file`: JSON header and NPZ arrays, never pickle).

May import: :mod:`pneufdd.diagnosis.detection`, :mod:`pneufdd.diagnosis.effects`,
:mod:`pneufdd.diagnosis.localisation` and the layers below :mod:`pneufdd.diagnosis`.
"""
