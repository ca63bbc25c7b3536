"""Leak effects: what a set of leaks does to one machine's per-step features.

Owns the leak-effect model (:mod:`.model`, :class:`LeakEffectModel`): the twin's
signatures of single leaks and pairs (:mod:`.signatures`, built by :mod:`.twin`), the
piecewise-linear size model between them (:mod:`.piecewise`) and the model uncertainty
measured on plausible plants. Localisation asks this package, and only this package,
what leaks would look like.

May import: :mod:`pneufdd.errors`, :mod:`pneufdd.location`, :mod:`pneufdd.physics`,
:mod:`pneufdd.sim`, :mod:`pneufdd.signals`, :mod:`pneufdd.features` and
:mod:`pneufdd.parallel`; nothing else of :mod:`pneufdd.diagnosis`.
"""
