"""Energy beyond leaks (section 6.2.1): where the air goes, the lowest pressure, what-ifs.

May import: :mod:`pneufdd.calibration`, :mod:`pneufdd.diagnosis`, :mod:`pneufdd.features`,
:mod:`pneufdd.sim` and the layers below; not classifiers, evaluation, monitor, report
or cli.
"""

from __future__ import annotations
