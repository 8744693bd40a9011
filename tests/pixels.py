"""Test pixels: every bit pattern a dtype has room for, shared by the image codecs' tests."""

from __future__ import annotations

from typing import Any

import numpy as np

RNG = np.random.default_rng(23)


def sample_pixels(dtype: Any, shape: tuple[int, int, int]) -> np.ndarray:
    """Pixels of every bit pattern a dtype has room for (floats: finite, from their bytes' range)."""
    dtype = np.dtype(dtype)
    if dtype.kind == "f":
        return RNG.uniform(-1e3, 1e3, shape).astype(dtype)
    info = np.iinfo(dtype)
    native = dtype.newbyteorder("=")
    return RNG.integers(info.min, info.max, shape, dtype=native, endpoint=True).astype(dtype)
