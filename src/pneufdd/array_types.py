"""The array type aliases every layer shares (one definition, used everywhere).

``FloatArray`` holds SI values (float64), ``IntArray`` sample indices and counts
(int64), ``BoolArray`` masks. They are aliases of :data:`numpy.typing.NDArray`, for
annotations only.
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

__all__ = ["BoolArray", "FloatArray", "IntArray"]

FloatArray = npt.NDArray[np.float64]
IntArray = npt.NDArray[np.int64]
BoolArray = npt.NDArray[np.bool_]
