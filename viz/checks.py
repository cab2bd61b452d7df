"""Input checks shared by the recordings and the figures."""

from __future__ import annotations

import numpy as np

from core.exceptions import ConfigError


def check_array(name: str, a, shape: tuple) -> np.ndarray:
    """``a`` as a finite float array of ``shape`` (``-1`` = any length), or ConfigError."""
    x = np.asarray(a, dtype=float)
    ok = x.ndim == len(shape) and all(s in (-1, d) for s, d in zip(shape, x.shape))
    if not ok:
        want = "(" + ", ".join("n" if s == -1 else str(s) for s in shape) + ")"
        raise ConfigError(f"{name}: expected shape {want}, got {x.shape}")
    if not np.all(np.isfinite(x)):
        raise ConfigError(f"{name}: contains NaN or inf")
    return x


def same_len(**arrays) -> int:
    """The common length of the arrays, or ConfigError naming them."""
    lens = {k: len(v) for k, v in arrays.items()}
    if len(set(lens.values())) > 1:
        raise ConfigError("length mismatch: " + ", ".join(f"{k}={v}" for k, v in lens.items()))
    return next(iter(lens.values()))


def outlier_mask(outlier_rows, n: int) -> np.ndarray:
    """(n,) bool, True at the report's outlier rows (0-based); an index outside 0..n-1 is refused."""
    bad = np.zeros(n, bool)
    rows = np.asarray(list(outlier_rows), dtype=int)
    if rows.size and (rows.min() < 0 or rows.max() >= n):
        raise ConfigError(f"outlier_rows: index out of range 0..{n - 1}")
    bad[rows] = True
    return bad


def check_directions(direction: np.ndarray) -> None:
    """ConfigError unless every reading's approach direction is +1 or -1."""
    if not np.all(np.isin(direction, (1, -1))):
        raise ConfigError("direction: each reading's must be +1 or -1")
