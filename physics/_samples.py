"""Arguments of the vectorised physics functions: a scalar or one value per sample."""

from __future__ import annotations

import numpy as np


def per_sample(value: np.ndarray | float, n: int, name: str) -> np.ndarray:
    """``value`` as a contiguous float64 array of length n (a scalar repeated).

    >>> per_sample(2.0, 3, "dt").tolist()
    [2.0, 2.0, 2.0]
    """
    arr = np.asarray(value, dtype=np.float64)
    if arr.ndim == 0:
        return np.full(n, float(arr))
    if arr.shape != (n,):
        raise ValueError(f"{name}: expected a scalar or shape ({n},), got {arr.shape}")
    return np.ascontiguousarray(arr)
